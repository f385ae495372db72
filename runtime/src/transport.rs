//! [`IpcTransport`]: a node's declared inputs and outputs as iceoryx2 ports.

use std::any::Any;
use std::rc::Rc;

use harvest_ipc::catalogue::{Channel, EMERGENCY_STOP, OPERATOR_MODE};
use harvest_ipc::error::{IpcError, ReceiveError, WaitError};
use harvest_ipc::payload::Payload;
use harvest_ipc::payloads::{EmergencyStop, OperatorModeState};
use harvest_ipc::{Context, Ipc, Publisher, Subscriber, WaitSetGuard, Waiter};
use harvest_node::in_place::{LatestInPlace, Loaned};
use harvest_node::ports::{Drain, Latest, Out};
use harvest_node::{InputVisitor, Inputs, OutputVisitor, Outputs, Transport};

use crate::in_place::{HeldSample, LoanHolder};

/// A subscriber of any payload: what the transport reads through and what a wait set can
/// wake on.
pub(crate) trait InputPort: Any {
    fn topic(&self) -> &'static str;
    fn as_any(&self) -> &dyn Any;
    /// Wakes `waiter` when a sample arrives on this port's channel.
    fn attach<'a>(&'a self, waiter: &'a Waiter) -> Result<WaitSetGuard<'a, 'a, Ipc>, WaitError>;
}

impl<T: Payload + 'static> InputPort for Subscriber<T> {
    fn topic(&self) -> &'static str {
        self.channel().spec.topic
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn attach<'a>(&'a self, waiter: &'a Waiter) -> Result<WaitSetGuard<'a, 'a, Ipc>, WaitError> {
        waiter.attach_listener(self.listener())
    }
}

/// Stands for an output whose publisher lives in its slot's holder (a [`Loaned`] slot).
struct HeldBySlot;

/// The ports of one node: the stop and the mode (when the node obeys them), then one
/// subscriber per declared input and one publisher per declared output, in the order the
/// node visits them.
pub struct IpcTransport {
    emergency_stop: Option<Subscriber<EmergencyStop>>,
    operator_mode: Option<Subscriber<OperatorModeState>>,
    inputs: Vec<Rc<dyn InputPort>>,
    outputs: Vec<Box<dyn Any>>,
}

impl std::fmt::Debug for IpcTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IpcTransport")
            .field("obeys", &self.emergency_stop.is_some())
            .field("inputs", &self.inputs.len())
            .field("outputs", &self.outputs.len())
            .finish()
    }
}

struct OpenInputs<'a> {
    context: &'a Context,
    ports: Vec<Rc<dyn InputPort>>,
}

impl InputVisitor for OpenInputs<'_> {
    type Error = IpcError;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Latest<T>,
    ) -> Result<(), IpcError> {
        self.ports.push(Rc::new(self.context.subscriber(channel)?));
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Drain<T>,
    ) -> Result<(), IpcError> {
        self.ports.push(Rc::new(self.context.subscriber(channel)?));
        Ok(())
    }

    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut LatestInPlace<T>,
    ) -> Result<(), IpcError> {
        self.ports.push(Rc::new(self.context.subscriber(channel)?));
        slot.attach(Box::new(HeldSample::<T> { sample: None }));
        Ok(())
    }
}

struct OpenOutputs<'a> {
    context: &'a Context,
    ports: Vec<Box<dyn Any>>,
}

impl OutputVisitor for OpenOutputs<'_> {
    type Error = IpcError;

    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Out<T>,
    ) -> Result<(), IpcError> {
        self.ports.push(Box::new(self.context.publisher(channel)?));
        Ok(())
    }

    fn loaned<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Loaned<T>,
    ) -> Result<(), IpcError> {
        slot.attach(Box::new(LoanHolder {
            publisher: self.context.publisher(channel)?,
            loan: None,
            error: None,
        }));
        self.ports.push(Box::new(HeldBySlot));
        Ok(())
    }
}

fn out_of_order<T: Payload>(channel: Channel<T>) -> IpcError {
    IpcError::Receive(ReceiveError {
        topic: channel.spec.topic,
        reason: "the node visited its slots in another order than when its ports were opened"
            .to_owned(),
    })
}

/// The subscriber an input slot was opened with (same visiting order, so same type).
fn subscriber<T: Payload + 'static>(
    ports: &[Rc<dyn InputPort>],
    index: usize,
    channel: Channel<T>,
) -> Result<&Subscriber<T>, IpcError> {
    ports
        .get(index)
        .and_then(|port| port.as_any().downcast_ref::<Subscriber<T>>())
        .ok_or_else(|| out_of_order(channel))
}

struct Fill<'a> {
    ports: &'a [Rc<dyn InputPort>],
    index: usize,
}

impl InputVisitor for Fill<'_> {
    type Error = IpcError;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), IpcError> {
        let subscriber = subscriber(self.ports, self.index, channel)?;
        self.index += 1;
        slot.begin();
        if let Some(sample) = subscriber.receive_latest()? {
            slot.set(*sample);
        }
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Drain<T>,
    ) -> Result<(), IpcError> {
        let subscriber = subscriber(self.ports, self.index, channel)?;
        self.index += 1;
        slot.begin();
        subscriber.drain(|sample| slot.push(*sample))?;
        Ok(())
    }

    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut LatestInPlace<T>,
    ) -> Result<(), IpcError> {
        let subscriber = subscriber(self.ports, self.index, channel)?;
        self.index += 1;
        let held = slot
            .holder_mut::<HeldSample<T>>()
            .ok_or_else(|| out_of_order(channel))?;
        // The previous tick's sample goes back first: at most one is held between ticks.
        held.sample = None;
        held.sample = subscriber.receive_latest()?;
        Ok(())
    }
}

struct Send<'a> {
    ports: &'a mut [Box<dyn Any>],
    index: usize,
}

impl OutputVisitor for Send<'_> {
    type Error = IpcError;

    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Out<T>,
    ) -> Result<(), IpcError> {
        let publisher = self
            .ports
            .get_mut(self.index)
            .and_then(|port| port.downcast_mut::<Publisher<T>>())
            .ok_or_else(|| out_of_order(channel))?;
        self.index += 1;
        slot.flush(|value| publisher.publish(value).map(|_| ()))?;
        // A latched channel's late joiner gets the last value at the writer's next tick, not at
        // its next change (the stop is sent on change).
        if channel.spec.qos.history_size > 0 {
            publisher.update_connections()?;
        }
        Ok(())
    }

    fn loaned<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Loaned<T>,
    ) -> Result<(), IpcError> {
        self.index += 1;
        let (send, holder) = slot.take_send::<LoanHolder<T>>();
        let holder = holder.ok_or_else(|| out_of_order(channel))?;
        holder.flush(send)?;
        Ok(())
    }
}

impl IpcTransport {
    /// Opens the ports a node's slots declare (each slot visited once), with the stop and the
    /// mode every node that drives actuators obeys.
    pub fn open<I: Inputs, O: Outputs>(
        context: &Context,
        input_slots: &mut I,
        output_slots: &mut O,
    ) -> Result<Self, IpcError> {
        Self::open_with(context, input_slots, output_slots, true)
    }

    /// [`Self::open`]; `obeys`: whether the node reads the stop and the mode (a node that
    /// drives no actuator, such as a sensor or perception, does not take a reader's place on
    /// those channels, and the runner sees neither: never stopped, never held).
    pub fn open_with<I: Inputs, O: Outputs>(
        context: &Context,
        input_slots: &mut I,
        output_slots: &mut O,
        obeys: bool,
    ) -> Result<Self, IpcError> {
        let mut inputs = OpenInputs {
            context,
            ports: Vec::new(),
        };
        input_slots.visit(&mut inputs)?;
        let mut outputs = OpenOutputs {
            context,
            ports: Vec::new(),
        };
        output_slots.visit(&mut outputs)?;
        let (emergency_stop, operator_mode) = if obeys {
            (
                Some(context.subscriber(EMERGENCY_STOP)?),
                Some(context.subscriber(OPERATOR_MODE)?),
            )
        } else {
            (None, None)
        };
        Ok(Self {
            emergency_stop,
            operator_mode,
            inputs: inputs.ports,
            outputs: outputs.ports,
        })
    }

    /// The subscriber of a declared input, by topic (to wake on its events).
    pub(crate) fn input_port(&self, topic: &str) -> Option<Rc<dyn InputPort>> {
        self.inputs
            .iter()
            .find(|port| port.topic() == topic)
            .cloned()
    }
}

impl Transport for IpcTransport {
    type Error = IpcError;

    fn emergency_stop(&mut self) -> Result<Option<bool>, IpcError> {
        let Some(stop) = &self.emergency_stop else {
            return Ok(None);
        };
        Ok(stop.receive_latest()?.map(|stop| stop.engaged != 0))
    }

    fn operator_mode(&mut self) -> Result<Option<OperatorModeState>, IpcError> {
        let Some(mode) = &self.operator_mode else {
            return Ok(None);
        };
        Ok(mode.receive_latest()?.map(|mode| *mode))
    }

    fn read_inputs<I: Inputs>(&mut self, inputs: &mut I) -> Result<(), IpcError> {
        inputs.visit(&mut Fill {
            ports: &self.inputs,
            index: 0,
        })
    }

    fn publish<O: Outputs>(&mut self, outputs: &mut O) -> Result<(), IpcError> {
        outputs.visit(&mut Send {
            ports: &mut self.outputs,
            index: 0,
        })
    }
}
