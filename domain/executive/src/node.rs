//! The executive as a node ([`ExecutiveNode`]): [`harvest_operator::Executive`] between its
//! channels and its devices ([`crate::devices`]).
//!
//! Per tick, after the runner read the stop and the devices:
//! 1. the newest state of each arm, the platform's and the tractor's readings; along a row the
//!    newest detection set and the new harvest events go to the stop cycle;
//! 2. a violation on `safety/violation` whose action is `stop` (the independent safety
//!    monitor) engages the protective stop ([`Executive::protective_stop`]; release stays an
//!    operator command); then every command on `operator/command` goes through
//!    [`Executive::handle`]; its actions become messages (`safety/emergency_stop`,
//!    `armN/manual`) and device commands (the platform) of this tick; "next stop" goes to the
//!    row's stop cycle, whose refusal becomes the acknowledgement's. The acknowledgements go
//!    out on `operator/ack` once the devices were written ([`Node::finish`]): a platform that
//!    refused turns an accepted platform command into a refusal;
//! 3. [`Executive::tick`] stops a manual motion whose controlling session went silent;
//! 4. the row's cycle ticks while harvesting;
//! 5. `operator/mode` is published on every change and at 10 Hz (with `field_hold` while the
//!    row repositions), and the mode file is written when the mode or the arms change.
//!
//! So an e-stop command reaches `safety/emergency_stop` within one executive period of its
//! arrival, and the arms and the vacuum supervisor obey it at their next tick.
//!
//! At start the node waits up to [`START_WAIT_NS`] for both arms' states: an arm that reports
//! itself stopped, or an engaged `safety/emergency_stop` (from an earlier executive), makes the
//! executive start e-stopped and publish the stop again; the e-stop is never released
//! implicitly. Commands and violations heard meanwhile are kept and handled once it starts.

use std::collections::VecDeque;

use harvest_field::StopCycleError;
use harvest_hw::platform::Platform;
use harvest_hw::tractor::Tractor;
use harvest_ipc::catalogue::{
    ARM_MANUAL, ARM_STATE, EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_ACK, OPERATOR_COMMAND,
    OPERATOR_MODE, PERCEPTION_APPLES, SAFETY_VIOLATION,
};
use harvest_ipc::payloads::{
    AppleDetections, ArmManualCommand, ArmPhase, ArmState, EmergencyStop, HarvestEvent,
    OperatorAck, OperatorCommand, OperatorModeCode, OperatorModeState, SafetyViolation,
};
use harvest_node::ports::{Drain, Latest, Out};
use harvest_node::{Applied, InputVisitor, Inputs, Node, NodeTick, OutputVisitor, Outputs};
use harvest_operator::{
    Action, ArmView, ControlToken, Decision, Executive, ExecutiveConfig, Refusal, StackView,
};

use crate::devices::{ExecutiveCommands, ExecutiveDevices, ExecutiveReadings, PlatformOrder};
use crate::messages;
use crate::row::{RowEffects, RowOptions, RowStack, RowWork};

/// `operator/mode` is re-sent this often, ns.
pub const MODE_PERIOD_NS: u64 = 100_000_000;
/// How long the start waits for both arms' states, ns.
pub const START_WAIT_NS: u64 = 200_000_000;

/// What the node is built from.
#[derive(Debug, Clone)]
pub struct ExecutiveNodeConfig {
    pub executive: ExecutiveConfig,
    pub token: ControlToken,
    /// The mode of an earlier executive of the same run (the mode file), if any.
    pub previous: Option<OperatorModeState>,
    /// Work a row (`None`: the robot stays where it is).
    pub row: Option<RowOptions>,
    /// The stages' travel `[in_out, up_down]`, m (the row's positioning).
    pub travel_max_m: [f64; 2],
}

/// The channels the executive reads.
pub struct ExecutiveInputs {
    commands: Drain<OperatorCommand>,
    violations: Drain<SafetyViolation>,
    arm_states: [Latest<ArmState>; 2],
    /// Along a row only.
    row: Option<(Latest<AppleDetections>, Drain<HarvestEvent>)>,
}

impl Inputs for ExecutiveInputs {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.drain(OPERATOR_COMMAND, &mut self.commands)?;
        v.drain(SAFETY_VIOLATION, &mut self.violations)?;
        v.latest(ARM_STATE[0], &mut self.arm_states[0])?;
        v.latest(ARM_STATE[1], &mut self.arm_states[1])?;
        if let Some((apples, events)) = &mut self.row {
            v.latest(PERCEPTION_APPLES, apples)?;
            v.drain(HARVEST_EVENTS, events)?;
        }
        Ok(())
    }
}

/// The channels the executive writes.
pub struct ExecutiveOutputs {
    estop: Out<EmergencyStop>,
    manual: [Out<ArmManualCommand>; 2],
    ack: Out<OperatorAck>,
    mode: Out<OperatorModeState>,
    /// Along a row only.
    events: Option<Out<HarvestEvent>>,
}

impl Outputs for ExecutiveOutputs {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.output(EMERGENCY_STOP, &mut self.estop)?;
        v.output(ARM_MANUAL[0], &mut self.manual[0])?;
        v.output(ARM_MANUAL[1], &mut self.manual[1])?;
        v.output(OPERATOR_ACK, &mut self.ack)?;
        v.output(OPERATOR_MODE, &mut self.mode)?;
        if let Some(events) = &mut self.events {
            v.output(HARVEST_EVENTS, events)?;
        }
        Ok(())
    }
}

/// An acknowledgement waiting for the devices' write.
#[derive(Debug)]
struct PendingAck {
    command: OperatorCommand,
    decision: Decision,
    /// Its acceptance depends on the platform taking this tick's order.
    platform: bool,
    /// The mode once it was decided.
    mode: OperatorModeCode,
}

/// The executive (module documentation), with a platform of type `P` and a tractor of type
/// `T`.
pub struct ExecutiveNode<P, T> {
    devices: std::marker::PhantomData<fn() -> (P, T)>,
    config: ExecutiveNodeConfig,
    platform_present: bool,
    executive: Option<Executive>,
    started_ns: Option<u64>,
    emergency_stop_seen: bool,
    row: Option<RowWork>,
    view: StackView,
    tractor: Option<(f64, bool)>,
    commands: VecDeque<OperatorCommand>,
    violations: VecDeque<SafetyViolation>,
    acks: Vec<PendingAck>,
    last_mode_ns: Option<u64>,
    published: Option<(u8, [bool; 2], u64, u64, bool)>,
    handled: u64,
}

impl<P: Platform, T: Tractor> ExecutiveNode<P, T> {
    /// The node for `devices` (whether a platform is present is theirs to say).
    pub fn new(
        config: ExecutiveNodeConfig,
        devices: &ExecutiveDevices<P, T>,
    ) -> Result<Self, StopCycleError> {
        let row = config
            .row
            .map(|options| RowWork::new(options, config.travel_max_m))
            .transpose()?;
        Ok(Self {
            devices: std::marker::PhantomData,
            platform_present: devices.platform_present(),
            executive: None,
            started_ns: None,
            emergency_stop_seen: false,
            row,
            view: StackView::default(),
            tractor: None,
            commands: VecDeque::new(),
            violations: VecDeque::new(),
            acks: Vec::new(),
            last_mode_ns: None,
            published: None,
            handled: 0,
            config,
        })
    }
}

impl<P, T> ExecutiveNode<P, T> {
    /// The mode machine, once started.
    pub fn executive(&self) -> Option<&Executive> {
        self.executive.as_ref()
    }

    /// The row's work, along a row.
    pub fn row(&self) -> Option<&RowWork> {
        self.row.as_ref()
    }

    /// Operator commands handled so far.
    pub fn handled(&self) -> u64 {
        self.handled
    }

    /// The executive's start: once both arms spoke or the start wait is over.
    fn start(
        &mut self,
        now_ns: u64,
        arm_states: &[Option<ArmState>; 2],
        outputs: &mut ExecutiveOutputs,
    ) {
        let started_ns = *self.started_ns.get_or_insert(now_ns);
        let both = arm_states.iter().all(Option::is_some);
        if !both && now_ns.saturating_sub(started_ns) < START_WAIT_NS {
            return;
        }
        let arm_stopped = arm_states
            .iter()
            .flatten()
            .any(|s| s.phase == ArmPhase::Stopped);
        let engaged = self.emergency_stop_seen || arm_stopped;
        let mut config = self.config.executive;
        config.field_row = self.row.is_some();
        let executive = Executive::new(
            config,
            self.config.token.clone(),
            now_ns,
            engaged,
            self.config.previous.as_ref(),
        );
        if engaged {
            outputs.estop.send(messages::emergency_stop(
                now_ns,
                true,
                "engaged before the executive started",
            ));
        }
        self.executive = Some(executive);
    }

    /// Carries out one action; `Err` when the platform is absent.
    fn apply(
        action: &Action,
        now_ns: u64,
        platform_present: bool,
        commands: &mut ExecutiveCommands,
        outputs: &mut ExecutiveOutputs,
    ) -> Result<(), Refusal> {
        match action {
            Action::EngageEmergencyStop { reason } => {
                outputs
                    .estop
                    .send(messages::emergency_stop(now_ns, true, reason));
            }
            Action::ReleaseEmergencyStop => outputs.estop.send(messages::emergency_stop(
                now_ns,
                false,
                "released by the operator",
            )),
            Action::ArmMoveTo { arm, .. } | Action::ArmStop { arm } => {
                if let Some(order) = messages::manual_order(now_ns, action) {
                    outputs.manual[usize::from(arm.saturating_sub(1)).min(1)].send(order);
                }
            }
            Action::PlatformMoveTo { target_m } if platform_present => {
                commands.platform = Some(PlatformOrder::MoveTo {
                    target_m: *target_m,
                });
            }
            Action::PlatformStop if platform_present => {
                commands.platform = Some(PlatformOrder::Stop);
            }
            // An e-stop's stop of the stages needs no platform.
            Action::PlatformStop => {}
            Action::PlatformMoveTo { .. } => return Err(Refusal::NoPlatform),
            // Carried out by the row's stop cycle where the command is handled.
            Action::NextStop => {}
        }
        Ok(())
    }
}

impl<P: Platform, T: Tractor> Node for ExecutiveNode<P, T> {
    type Inputs = ExecutiveInputs;
    type Outputs = ExecutiveOutputs;
    type Devices = ExecutiveDevices<P, T>;
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        "executive"
    }

    fn progress(&self) -> Option<u64> {
        Some(self.handled)
    }

    fn inputs(&self) -> ExecutiveInputs {
        ExecutiveInputs {
            commands: Drain::default(),
            violations: Drain::default(),
            arm_states: Default::default(),
            row: self.row.as_ref().map(|_| Default::default()),
        }
    }

    fn outputs(&self) -> ExecutiveOutputs {
        ExecutiveOutputs {
            estop: Out::default(),
            manual: Default::default(),
            ack: Out::default(),
            mode: Out::default(),
            events: self.row.as_ref().map(|_| Out::default()),
        }
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        readings: Option<&ExecutiveReadings>,
        inputs: &ExecutiveInputs,
        commands: &mut ExecutiveCommands,
        outputs: &mut ExecutiveOutputs,
    ) -> Result<(), Self::Error> {
        let now_ns = tick.now_ns;
        *commands = ExecutiveCommands::default();
        // 1. The stack.
        let readings = readings.copied().unwrap_or_default();
        self.view.platform = readings.platform;
        self.tractor = readings.tractor;
        self.emergency_stop_seen |= tick.emergency_stop;
        let arm_states = [
            inputs.arm_states[0].get().copied(),
            inputs.arm_states[1].get().copied(),
        ];
        self.view.arms = arm_states.map(|s| s.map(|s| ArmView::from_state(&s, now_ns)));
        let mut effects = RowEffects::default();
        if let (Some(row), Some((apples, events))) = (self.row.as_mut(), &inputs.row) {
            if let Some(set) = apples.fresh() {
                row.on_detections(set);
            }
            for event in events.items() {
                row.on_event(event);
            }
            if readings.tractor_past_end {
                row.on_row_end(now_ns, &mut effects);
            }
        }
        self.commands
            .extend(inputs.commands.items().iter().copied());
        self.violations
            .extend(inputs.violations.items().iter().copied());

        if self.executive.is_none() {
            self.start(now_ns, &arm_states, outputs);
        }
        let platform_present = self.platform_present;
        let Some(executive) = self.executive.as_mut() else {
            return Ok(());
        };

        // 2. The safety monitor's stop requests, then the operator's commands.
        while let Some(violation) = self.violations.pop_front() {
            if !violation.requests_stop() {
                continue;
            }
            let text = violation.description.as_str().to_owned();
            for action in executive.protective_stop(now_ns, &text) {
                let _ = Self::apply(&action, now_ns, platform_present, commands, outputs);
            }
        }
        let platform_now = self.view.platform.map(|p| (p.position_m, p.in_motion));
        while let Some(command) = self.commands.pop_front() {
            self.handled += 1;
            let mut decision = executive.handle(now_ns, &command, &self.view);
            let actions = std::mem::take(&mut decision.actions);
            let mut platform = false;
            for action in &actions {
                if *action == Action::NextStop {
                    // The row's stop cycle has the last word.
                    let outcome = match self.row.as_mut() {
                        Some(row) => {
                            let stack = RowStack {
                                arm_states: [arm_states[0].as_ref(), arm_states[1].as_ref()],
                                platform: platform_now,
                                tractor: self.tractor,
                            };
                            row.next_stop(now_ns, &stack, &mut effects)
                        }
                        None => Err(Refusal::NoRow.to_string()),
                    };
                    match outcome {
                        Ok(what) => decision.reason = what,
                        Err(reason) => decision.refuse(Refusal::NextStop(reason)),
                    }
                    continue;
                }
                platform |= matches!(action, Action::PlatformMoveTo { .. } | Action::PlatformStop)
                    && platform_present;
                if let Err(refusal) =
                    Self::apply(action, now_ns, platform_present, commands, outputs)
                {
                    decision.refuse(refusal);
                }
            }
            self.acks.push(PendingAck {
                command,
                decision,
                platform,
                mode: executive.mode(),
            });
        }

        // 3. Silent sessions.
        for action in executive.tick(now_ns, &self.view) {
            let _ = Self::apply(&action, now_ns, platform_present, commands, outputs);
        }

        // 4. The row's stop-and-go cycle (only while harvesting).
        let harvesting = executive.mode() == OperatorModeCode::Harvesting;
        if let Some(row) = self.row.as_mut() {
            let stack = RowStack {
                arm_states: [arm_states[0].as_ref(), arm_states[1].as_ref()],
                platform: platform_now,
                tractor: self.tractor,
            };
            row.tick(now_ns, harvesting, &stack, &mut effects);
        }
        if let Some(target_m) = effects.platform_target_m {
            if platform_present {
                commands.platform = Some(PlatformOrder::MoveTo { target_m });
            } else {
                tracing::warn!(?target_m, "platform move of the row: no platform");
            }
        }
        commands.tractor_advance_m = effects.tractor_advance_m;
        if let Some(events) = outputs.events.as_mut() {
            effects
                .events
                .into_iter()
                .for_each(|event| events.send(event));
        }

        // 5. The mode.
        let field_hold = self.row.as_ref().is_some_and(RowWork::holds_approaches);
        let key = (
            executive.mode() as u8,
            executive.arms_enabled(),
            executive.last_change().at_ns,
            executive.controller().map_or(0, |c| c.session_id),
            field_hold,
        );
        let changed = self.published != Some(key);
        if changed
            || self
                .last_mode_ns
                .is_none_or(|last| now_ns.saturating_sub(last) >= MODE_PERIOD_NS)
        {
            outputs.mode.send(messages::mode_state(
                now_ns,
                executive,
                platform_present,
                field_hold,
                self.view.platform.as_ref(),
            ));
            self.last_mode_ns = Some(now_ns);
            if changed && self.published.is_none_or(|p| (p.0, p.1) != (key.0, key.1)) {
                commands.save_mode = Some((executive.mode(), executive.arms_enabled()));
            }
            self.published = Some(key);
        }
        Ok(())
    }

    fn finish(&mut self, tick: &NodeTick, applied: Applied, outputs: &mut ExecutiveOutputs) {
        for mut pending in self.acks.drain(..) {
            if pending.platform && applied != Applied::Written {
                let reason = match applied {
                    Applied::Safe => "the emergency stop is engaged".to_owned(),
                    _ => "the platform refused or did not answer".to_owned(),
                };
                pending.decision.refuse(Refusal::NoPlatform);
                pending.decision.reason = reason;
            }
            outputs.ack.send(messages::ack(
                tick.now_ns,
                &pending.command,
                &pending.decision,
                pending.mode,
            ));
        }
    }
}

#[cfg(test)]
mod tests;
