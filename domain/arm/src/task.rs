//! The arm as a runtime node ([`ArmTask`]): its channels, its servos ([`ArmDevices`]) and the
//! glue between [`ArmNode`] and the channels. The tick around it (the stop first, device
//! faults, the operator's mode, health) is the runtime's ([`harvest_node::Runner`]).

use harvest_hw::arm_servos::ArmServos;
use harvest_ipc::Header;
use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_MANUAL, ARM_STATE, ARM_TARGET, HARVEST_EVENTS, VACUUM_STATE, VALVE_GRANT,
    VALVE_REQUEST,
};
use harvest_ipc::payloads::{
    ArmCommand, ArmManualCommand, ArmManualKind, ArmPhase as PhaseCode, ArmState, ArmTarget,
    HarvestEvent, HarvestEventKind, VacuumState, ValveGrant, ValveRequest, ValveRequestKind,
};
use harvest_node::ports::{Drain, Latest, Out};
use harvest_node::{
    Applied, Devices, InputVisitor, Inputs, Node, NodeTick, OutputVisitor, Outputs,
};
use harvest_robot_model::params::ArmId;

use crate::harvest_events::ArmEventReporter;
use crate::node::{ArmNode, ArmNodeInput, ArmNodeOutput, EncoderSample, OtherArmInput, ServoOrder};

/// The standing valve request is sent again this often when unchanged, ms (so a restarted
/// vacuum supervisor learns it): the arm process's default.
pub const DEFAULT_VALVE_REQUEST_RESEND_MS: u64 = 500;

/// The servos as the runtime drives them.
#[derive(Debug)]
pub struct ArmDevices<S>(pub S);

/// One tick's servo order.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub enum ServoCommand {
    /// Nothing (the arm is not ready yet).
    #[default]
    None,
    Track {
        position: [f64; 4],
        velocity: [f64; 4],
    },
    Hold,
}

impl<S: ArmServos> Devices for ArmDevices<S> {
    type Readings = EncoderSample;
    type Commands = ServoCommand;
    type Error = S::Error;

    fn stop(&mut self) -> Result<(), S::Error> {
        self.0.hold()
    }

    fn hold(&mut self) -> Result<(), S::Error> {
        self.0.hold()
    }

    fn read(&mut self, _now_ns: u64) -> Result<Option<EncoderSample>, S::Error> {
        Ok(self.0.feedback()?.map(|f| EncoderSample {
            capture_ns: f.capture_ns,
            position: f.position,
            velocity: f.velocity,
        }))
    }

    fn write(&mut self, commands: &ServoCommand) -> Result<(), S::Error> {
        match *commands {
            ServoCommand::None => Ok(()),
            ServoCommand::Track { position, velocity } => self.0.command(position, velocity),
            ServoCommand::Hold => self.0.hold(),
        }
    }
}

/// The channels the arm reads.
pub struct ArmInputs {
    arm: ArmId,
    target: Latest<ArmTarget>,
    vacuum: Latest<VacuumState>,
    grants: Drain<ValveGrant>,
    other_state: Latest<ArmState>,
    other_target: Latest<ArmTarget>,
    manual: Drain<ArmManualCommand>,
}

impl Inputs for ArmInputs {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        let (i, other) = (self.arm.index(), 1 - self.arm.index());
        v.latest(ARM_TARGET[i], &mut self.target)?;
        v.latest(VACUUM_STATE, &mut self.vacuum)?;
        v.drain(VALVE_GRANT, &mut self.grants)?;
        v.latest(ARM_STATE[other], &mut self.other_state)?;
        v.latest(ARM_TARGET[other], &mut self.other_target)?;
        v.drain(ARM_MANUAL[i], &mut self.manual)
    }
}

/// The channels the arm writes.
pub struct ArmOutputs {
    arm: ArmId,
    events: Out<HarvestEvent>,
    command: Out<ArmCommand>,
    state: Out<ArmState>,
    request: Out<ValveRequest>,
}

impl Outputs for ArmOutputs {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        let i = self.arm.index();
        v.output(HARVEST_EVENTS, &mut self.events)?;
        v.output(ARM_COMMAND[i], &mut self.command)?;
        v.output(ARM_STATE[i], &mut self.state)?;
        v.output(VALVE_REQUEST, &mut self.request)
    }
}

/// One arm: [`ArmNode`] between its channels (module documentation), for servos of type `S`.
pub struct ArmTask<S> {
    servos: std::marker::PhantomData<fn() -> S>,
    node: ArmNode,
    reporter: ArmEventReporter,
    name: String,
    /// The servos reported once: until then nothing is stepped or published.
    ready: bool,
    /// This arm's newest answer on the shared grant channel.
    grant: Option<ValveGrant>,
    /// The standing valve request as last sent, and when.
    last_request: Option<(ValveRequest, u64)>,
    resend_ns: u64,
    /// This tick's servo order and the joints it was computed from.
    servo: ServoOrder,
    joint_position: [f64; 4],
}

impl<S> ArmTask<S> {
    pub fn new(node: ArmNode, valve_request_resend_ms: u64) -> Self {
        let arm = node.arm();
        Self {
            servos: std::marker::PhantomData,
            reporter: ArmEventReporter::new(arm),
            name: format!("arm{}", arm.number()),
            node,
            ready: false,
            grant: None,
            last_request: None,
            resend_ns: valve_request_resend_ms * 1_000_000,
            servo: ServoOrder::Hold,
            joint_position: [0.0; 4],
        }
    }

    pub fn node(&self) -> &ArmNode {
        &self.node
    }

    /// What the node did at the last tick (its events, servo order and state); `None` when it
    /// did not step (the servos had not reported yet).
    pub fn last_output(&self) -> Option<&ArmNodeOutput> {
        // Once ready, the node steps at every tick.
        self.ready.then(|| self.node.last_output())
    }

    /// Carries out manual orders in manual mode only; stops a manual move when the mode left
    /// manual or went silent.
    fn obey_manual(&mut self, now_ns: u64, manual_allowed: bool, orders: &[ArmManualCommand]) {
        let number = self.node.arm().number();
        for order in orders.iter().filter(|o| o.arm_id == number) {
            match order.manual_kind() {
                Some(ArmManualKind::MoveTo) if manual_allowed => {
                    match self.node.start_manual(
                        now_ns,
                        order.goal_joint_position,
                        order.speed_fraction,
                        order.request_id,
                    ) {
                        Ok(duration_s) => {
                            tracing::info!(request_id = order.request_id, duration_s, "manual move")
                        }
                        Err(refusal) => tracing::warn!(request_id = order.request_id, %refusal,
                            "manual move refused"),
                    }
                }
                Some(ArmManualKind::MoveTo) => tracing::warn!(
                    request_id = order.request_id,
                    "manual move refused: not in manual mode"
                ),
                Some(ArmManualKind::Stop) => self.node.stop_manual(),
                None => tracing::warn!(kind = order.kind, "unknown manual order ignored"),
            }
        }
        if self.node.manual_active() && !manual_allowed {
            tracing::warn!("manual move stopped: mode left manual or went silent");
            self.node.stop_manual();
        }
    }
}

impl<S: ArmServos> Node for ArmTask<S> {
    type Inputs = ArmInputs;
    type Outputs = ArmOutputs;
    type Devices = ArmDevices<S>;
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        &self.name
    }

    fn inputs(&self) -> ArmInputs {
        ArmInputs {
            arm: self.node.arm(),
            target: Latest::default(),
            vacuum: Latest::default(),
            grants: Drain::default(),
            other_state: Latest::default(),
            other_target: Latest::default(),
            manual: Drain::default(),
        }
    }

    fn outputs(&self) -> ArmOutputs {
        ArmOutputs {
            arm: self.node.arm(),
            events: Out::default(),
            command: Out::default(),
            state: Out::default(),
            request: Out::default(),
        }
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        readings: Option<&EncoderSample>,
        inputs: &ArmInputs,
        commands: &mut ServoCommand,
        outputs: &mut ArmOutputs,
    ) -> Result<(), Self::Error> {
        // Until the servos report for the first time the arm is not ready: nothing is stepped
        // or published (no state: the vacuum supervisor assigns it nothing and the other arm
        // defers its motions).
        self.ready |= readings.is_some();
        if !self.ready {
            *commands = ServoCommand::None;
            return Ok(());
        }
        let now_ns = tick.now_ns;
        let number = self.node.arm().number();
        if let Some(grant) = inputs
            .grants
            .items()
            .iter()
            .rev()
            .find(|g| g.arm_id == number)
        {
            self.grant = Some(*grant);
        }
        self.node
            .hold_targets(tick.obedience.targets_held[self.node.arm().index()]);
        self.obey_manual(now_ns, tick.obedience.manual, inputs.manual.items());

        let input = ArmNodeInput {
            now_ns,
            feedback: readings.copied(),
            target: inputs.target.get(),
            vacuum: inputs.vacuum.get(),
            grant: self.grant.as_ref(),
            other_arm: inputs.other_state.get().map(|state| OtherArmInput {
                state,
                target: inputs.other_target.get(),
            }),
            emergency_stop: tick.emergency_stop,
        };
        let out = self.node.step(&input);
        self.servo = out.servo;
        self.joint_position = out.state.joint_position;
        *commands = match out.servo {
            ServoOrder::Track { position, velocity } => ServoCommand::Track { position, velocity },
            ServoOrder::Hold => ServoCommand::Hold,
        };

        // The node's own state: its phase code is always known.
        let phase = out.state.phase.get().unwrap_or(PhaseCode::Idle);
        for event in &out.events {
            if let Some(harvest_event) =
                self.reporter
                    .convert(now_ns, phase, event, inputs.target.get())
            {
                if harvest_event.kind == HarvestEventKind::TargetRejected {
                    tracing::info!(apple_id = harvest_event.apple_id,
                        reason = %harvest_event.reason, "target rejected");
                }
                outputs.events.send(harvest_event);
            }
        }
        self.reporter.end_tick();
        outputs.state.send(out.state);
        let request = out.valve_request;
        let due = match self.last_request {
            None => true,
            Some((last, at_ns)) => {
                last.request_seq != request.request_seq
                    || last.kind != request.kind
                    || now_ns.saturating_sub(at_ns) >= self.resend_ns
            }
        };
        if due {
            let mut message = request;
            message.header.capture_ns = now_ns;
            outputs.request.send(message);
            self.last_request = Some((request, now_ns));
        }
        Ok(())
    }

    fn finish(&mut self, tick: &NodeTick, applied: Applied, outputs: &mut ArmOutputs) {
        if !self.ready {
            return;
        }
        if applied == Applied::Refused {
            tracing::debug!(servo = ?self.servo, "servo command refused: braked");
        }
        let (position, velocity) = match self.servo {
            ServoOrder::Track { position, velocity } if applied == Applied::Written => {
                (position, velocity)
            }
            _ => (self.joint_position, [0.0; 4]),
        };
        let held = !matches!(
            (self.servo, applied),
            (ServoOrder::Track { .. }, Applied::Written)
        );
        let (apple_id, source_capture_ns) = self
            .reporter
            .current_target()
            .map_or((0, 0), |t| (t.apple_id, t.source_capture_ns));
        outputs.command.send(ArmCommand {
            header: Header {
                capture_ns: tick.now_ns,
                ..Header::default()
            },
            arm_id: self.node.arm().number(),
            hold: u8::from(held),
            _reserved: [0; 2],
            apple_id,
            source_capture_ns,
            joint_position: position,
            joint_velocity: velocity,
        });
    }

    fn on_exit(&mut self, now_ns: u64, outputs: &mut ArmOutputs) {
        // Leave the valve closed: the arm is braked by the runtime already.
        outputs.request.send(ValveRequest {
            header: Header {
                capture_ns: now_ns,
                ..Header::default()
            },
            arm_id: self.node.arm().number(),
            kind: ValveRequestKind::Close.into(),
            _reserved: [0; 2],
            request_seq: self
                .last_request
                .map_or(0, |(r, _)| r.request_seq.wrapping_add(1)),
        });
    }
}
