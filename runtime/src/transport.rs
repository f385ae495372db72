//! [`IpcTransport`]: a node's declared inputs and outputs as iceoryx2 ports.

use std::any::Any;

use harvest_ipc::catalogue::{Channel, EMERGENCY_STOP, OPERATOR_MODE};
use harvest_ipc::error::{IpcError, ReceiveError};
use harvest_ipc::payload::Payload;
use harvest_ipc::payloads::{EmergencyStop, OperatorModeState};
use harvest_ipc::{Context, Publisher, Subscriber};
use harvest_node::ports::{Drain, Latest, Out};
use harvest_node::{InputVisitor, Inputs, OutputVisitor, Outputs, Transport};

/// The ports of one node: the stop and the mode (every node's), then one subscriber per
/// declared input and one publisher per declared output, in the order the node visits them.
pub struct IpcTransport {
    emergency_stop: Subscriber<EmergencyStop>,
    operator_mode: Subscriber<OperatorModeState>,
    inputs: Vec<Box<dyn Any>>,
    outputs: Vec<Box<dyn Any>>,
}

impl std::fmt::Debug for IpcTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("IpcTransport")
            .field("inputs", &self.inputs.len())
            .field("outputs", &self.outputs.len())
            .finish()
    }
}

struct OpenInputs<'a> {
    context: &'a Context,
    ports: Vec<Box<dyn Any>>,
}

impl InputVisitor for OpenInputs<'_> {
    type Error = IpcError;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Latest<T>,
    ) -> Result<(), IpcError> {
        self.ports.push(Box::new(self.context.subscriber(channel)?));
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        _: &mut Drain<T>,
    ) -> Result<(), IpcError> {
        self.ports.push(Box::new(self.context.subscriber(channel)?));
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
}

/// The port a slot was opened with (same visiting order, so same type).
fn port<P: 'static, T: Payload>(
    ports: &mut [Box<dyn Any>],
    index: usize,
    channel: Channel<T>,
) -> Result<&mut P, IpcError> {
    ports
        .get_mut(index)
        .and_then(|port| port.downcast_mut::<P>())
        .ok_or_else(|| {
            IpcError::Receive(ReceiveError {
                topic: channel.spec.topic,
                reason: "the node visited its slots in another order than when its ports \
                         were opened"
                    .to_owned(),
            })
        })
}

struct Fill<'a> {
    ports: &'a mut [Box<dyn Any>],
    index: usize,
}

impl InputVisitor for Fill<'_> {
    type Error = IpcError;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), IpcError> {
        let subscriber: &mut Subscriber<T> = port(self.ports, self.index, channel)?;
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
        let subscriber: &mut Subscriber<T> = port(self.ports, self.index, channel)?;
        self.index += 1;
        slot.begin();
        subscriber.drain(|sample| slot.push(*sample))?;
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
        let publisher: &mut Publisher<T> = port(self.ports, self.index, channel)?;
        self.index += 1;
        slot.flush(|value| publisher.publish(value).map(|_| ()))?;
        Ok(())
    }
}

impl IpcTransport {
    /// Opens the ports a node's slots declare (each slot visited once).
    pub fn open<I: Inputs, O: Outputs>(
        context: &Context,
        input_slots: &mut I,
        output_slots: &mut O,
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
        Ok(Self {
            emergency_stop: context.subscriber(EMERGENCY_STOP)?,
            operator_mode: context.subscriber(OPERATOR_MODE)?,
            inputs: inputs.ports,
            outputs: outputs.ports,
        })
    }
}

impl Transport for IpcTransport {
    type Error = IpcError;

    fn emergency_stop(&mut self) -> Result<Option<bool>, IpcError> {
        Ok(self
            .emergency_stop
            .receive_latest()?
            .map(|stop| stop.engaged != 0))
    }

    fn operator_mode(&mut self) -> Result<Option<OperatorModeState>, IpcError> {
        Ok(self.operator_mode.receive_latest()?.map(|mode| *mode))
    }

    fn read_inputs<I: Inputs>(&mut self, inputs: &mut I) -> Result<(), IpcError> {
        inputs.visit(&mut Fill {
            ports: &mut self.inputs,
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
