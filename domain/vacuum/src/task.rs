//! The vacuum supervisor as a runtime node ([`VacuumTask`]): its channels, its valve board
//! ([`BoardDevices`]) and the glue between [`VacuumNode`] and the channels (targets, answers,
//! state, events, completion). The tick around it (the stop first, device faults, the
//! operator's mode, health) is the runtime's ([`harvest_node::Runner`]).

use harvest_hw::valve_board::{ValveBoard, ValveId, ValveState};
use harvest_ipc::FixedString;
use harvest_ipc::catalogue::{
    ARM_STATE, ARM_TARGET, HARVEST_EVENTS, PERCEPTION_APPLES, VACUUM_STATE, VALVE_GRANT,
    VALVE_REQUEST,
};
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase as PhaseCode, ArmState, ArmTarget, HarvestEvent, HarvestEventKind,
    HarvestEventSource, VacuumState, ValveGrant, ValveRequest,
};
use harvest_node::ports::{Drain, Latest, Out};
use harvest_node::{
    Applied, Devices, InputVisitor, Inputs, Node, NodeTick, OutputVisitor, Outputs,
};

use crate::completion::CompletionWatch;
use crate::harvest_events::{ArmContext, vacuum_event};
use crate::node::{BoardReadings, VacuumNode, VacuumNodeInput};

/// The valve board as the runtime drives it, with the position last sent per valve (unknown
/// until the first command, and after a refused one, so that it is sent again).
#[derive(Debug)]
pub struct BoardDevices<B> {
    board: B,
    applied: [Option<bool>; 4],
}

impl<B> BoardDevices<B> {
    pub fn new(board: B) -> Self {
        Self {
            board,
            applied: [None; 4],
        }
    }

    /// The board (a re-run tells it what to answer).
    pub fn board_mut(&mut self) -> &mut B {
        &mut self.board
    }
}

/// One tick's valve commands.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ValveCommands {
    /// Position of valves 1-4 (true = open).
    pub open: [bool; 4],
    /// Close every valve at once first (the node's stop).
    pub close_all: bool,
}

impl<B: ValveBoard> BoardDevices<B> {
    fn close_all(&mut self) -> Result<(), B::Error> {
        match self.board.close_all() {
            Ok(()) => {
                self.applied = [Some(false); 4];
                Ok(())
            }
            Err(error) => {
                self.applied = [None; 4];
                Err(error)
            }
        }
    }
}

impl<B: ValveBoard> Devices for BoardDevices<B> {
    type Readings = BoardReadings;
    type Commands = ValveCommands;
    type Error = B::Error;

    /// Every valve closed (vented, cut off from the source); repeated until the board took it.
    fn stop(&mut self) -> Result<(), B::Error> {
        if self.applied == [Some(false); 4] {
            return Ok(());
        }
        self.close_all()
    }

    /// The valves stay where they are: closing them on a fault would drop a carried apple.
    fn hold(&mut self) -> Result<(), B::Error> {
        Ok(())
    }

    fn read(&mut self, now_ns: u64) -> Result<Option<BoardReadings>, B::Error> {
        let states = self.board.valve_states()?;
        let pressures = self.board.pressures()?;
        Ok(Some(BoardReadings {
            stamp_ns: now_ns,
            valve_open: states
                .0
                .map(|s| matches!(s, ValveState::Open | ValveState::Opening)),
            valve_in_transit: states.0.map(ValveState::is_in_transit),
            pressure_mmh2o: pressures.to_array(),
        }))
    }

    /// Sends the valves whose position changed; a refused one stays unknown and is sent again
    /// next tick (the first refusal is returned after the others were tried).
    fn write(&mut self, commands: &ValveCommands) -> Result<(), B::Error> {
        let mut first_error = None;
        if commands.close_all
            && self.applied != [Some(false); 4]
            && let Err(error) = self.close_all()
        {
            first_error = Some(error);
        }
        for (k, &open) in commands.open.iter().enumerate() {
            if self.applied[k] == Some(open) {
                continue;
            }
            match self.board.set_valve(ValveId(k as u8 + 1), open) {
                Ok(()) => self.applied[k] = Some(open),
                Err(error) => {
                    self.applied[k] = None;
                    first_error.get_or_insert(error);
                }
            }
        }
        first_error.map_or(Ok(()), Err)
    }
}

/// The channels the vacuum supervisor reads.
#[derive(Default)]
pub struct VacuumInputs {
    apples: Latest<AppleDetections>,
    arm_states: [Latest<ArmState>; 2],
    requests: Drain<ValveRequest>,
}

impl Inputs for VacuumInputs {
    fn visit<V: InputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.latest(PERCEPTION_APPLES, &mut self.apples)?;
        v.latest(ARM_STATE[0], &mut self.arm_states[0])?;
        v.latest(ARM_STATE[1], &mut self.arm_states[1])?;
        v.drain(VALVE_REQUEST, &mut self.requests)
    }
}

/// The channels the vacuum supervisor writes.
#[derive(Default)]
pub struct VacuumOutputs {
    targets: [Out<ArmTarget>; 2],
    grants: Out<ValveGrant>,
    state: Out<VacuumState>,
    events: Out<HarvestEvent>,
}

impl Outputs for VacuumOutputs {
    fn visit<V: OutputVisitor>(&mut self, v: &mut V) -> Result<(), V::Error> {
        v.output(ARM_TARGET[0], &mut self.targets[0])?;
        v.output(ARM_TARGET[1], &mut self.targets[1])?;
        v.output(VALVE_GRANT, &mut self.grants)?;
        v.output(VACUUM_STATE, &mut self.state)?;
        v.output(HARVEST_EVENTS, &mut self.events)
    }
}

/// The vacuum supervisor: [`VacuumNode`] between its channels, on a valve board of type `B`.
pub struct VacuumTask<B> {
    board: std::marker::PhantomData<fn() -> B>,
    node: VacuumNode,
    /// Arms that take part (`--arms`).
    enabled: [bool; 2],
    /// Each arm's standing valve request (newest per arm).
    requests: [Option<ValveRequest>; 2],
    completion: CompletionWatch,
    complete_after_ns: u64,
    /// Detection sets taken so far (the heartbeat's count).
    sets: u64,
}

impl<B> VacuumTask<B> {
    pub fn new(node: VacuumNode, enabled: [bool; 2], complete_after_ms: u64) -> Self {
        Self {
            board: std::marker::PhantomData,
            node,
            enabled,
            requests: [None; 2],
            completion: CompletionWatch::default(),
            complete_after_ns: complete_after_ms * 1_000_000,
            sets: 0,
        }
    }

    /// Detection sets taken so far.
    pub fn sets(&self) -> u64 {
        self.sets
    }

    /// The supervisor's node (its last outputs, its planner).
    pub fn node(&self) -> &VacuumNode {
        &self.node
    }
}

impl<B: ValveBoard> Node for VacuumTask<B> {
    type Inputs = VacuumInputs;
    type Outputs = VacuumOutputs;
    type Devices = BoardDevices<B>;
    type Error = std::convert::Infallible;

    fn name(&self) -> &str {
        "vacuum"
    }

    fn progress(&self) -> Option<u64> {
        Some(self.sets)
    }

    fn inputs(&self) -> VacuumInputs {
        VacuumInputs::default()
    }

    fn outputs(&self) -> VacuumOutputs {
        VacuumOutputs::default()
    }

    fn step(
        &mut self,
        tick: &NodeTick,
        readings: Option<&BoardReadings>,
        inputs: &VacuumInputs,
        commands: &mut ValveCommands,
        outputs: &mut VacuumOutputs,
    ) -> Result<(), Self::Error> {
        let now_ns = tick.now_ns;
        let detections = inputs.apples.fresh();
        self.sets += u64::from(detections.is_some());
        for request in inputs.requests.items() {
            if let Some(slot) = match request.arm_id {
                1 => Some(0),
                2 => Some(1),
                _ => None,
            } {
                self.requests[slot] = Some(*request);
            }
        }
        self.node.hold_dispatch(tick.obedience.targets_held);
        let arm_states = [inputs.arm_states[0].get(), inputs.arm_states[1].get()];
        let input = VacuumNodeInput {
            now_ns,
            arm_states,
            valve_requests: [self.requests[0].as_ref(), self.requests[1].as_ref()],
            readings: readings.copied(),
            detections,
            emergency_stop: tick.emergency_stop,
        };
        let out = self.node.step(&input);
        *commands = ValveCommands {
            open: out.valve_commands,
            close_all: out.close_all,
        };
        for (slot, target) in outputs.targets.iter_mut().zip(out.targets) {
            if let Some(target) = target {
                slot.send(target);
            }
        }
        for grant in out.grants.iter().flatten() {
            outputs.grants.send(*grant);
        }
        outputs.state.send(out.state);
        let arms = ArmContext {
            phase: arm_states.map(|s| s.map_or(PhaseCode::Idle.into(), |s| s.phase)),
            apple_id: arm_states.map(|s| s.map_or(0, |s| s.apple_id)),
        };
        for event in &out.events {
            self.completion.on_event(event);
            if let Some(harvest_event) = vacuum_event(now_ns, event, &arms) {
                if harvest_event.kind == HarvestEventKind::Assigned {
                    tracing::info!(arm = harvest_event.arm_id,
                        apple_id = harvest_event.apple_id,
                        position_m = ?harvest_event.position_in_robot_m, "apple assigned");
                }
                outputs.events.send(harvest_event);
            }
        }
        let arms_idle = (0..2)
            .all(|i| !self.enabled[i] || arm_states[i].is_some_and(|s| s.phase == PhaseCode::Idle));
        let idle = arms_idle && self.node.is_idle();
        if self.completion.update(now_ns, idle, self.complete_after_ns) {
            tracing::info!("harvest complete: nothing left to pick");
            let mut event = HarvestEvent::new(
                now_ns,
                HarvestEventSource::Vacuum,
                HarvestEventKind::HarvestComplete,
                0,
                0,
            );
            event.reason = FixedString::new("nothing assigned, dispatched or running");
            outputs.events.send(event);
        }
        Ok(())
    }

    fn finish(&mut self, _tick: &NodeTick, applied: Applied, _outputs: &mut VacuumOutputs) {
        if applied == Applied::Refused {
            tracing::debug!("a valve command was refused: sent again next tick");
        }
    }
}
