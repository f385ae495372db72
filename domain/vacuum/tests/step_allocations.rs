//! What the vacuum supervisor's 200 Hz tick allocates once running: `VacuumNode::step` (pressure
//! inference, re-planning on each detection set with Algorithm 1, attempts, valve answers,
//! dispatch) and the conversion of its events into `harvest/events` messages (`vacuum_event`),
//! the work the vacuum process does per tick between reading its inputs and publishing.
//! Counted on this thread with `harvest_ipc::allocation_counter` while two simulated arms pick
//! a tree of apples seen by the camera at 30 Hz, after a warm-up that runs the same way.

use harvest_ipc::allocation_counter::{self, CountingAllocator};
use harvest_ipc::payloads::{
    AppleDetection, AppleDetections, ArmPhase as PhaseCode, ArmState, ValveRequest,
    ValveRequestKind,
};
use harvest_robot_model::ArmId;
use harvest_vacuum::harvest_events::{ArmContext, vacuum_event};
use harvest_vacuum::node::{BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeInput};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const MS: u64 = 1_000_000;
const PERIOD_NS: u64 = 5 * MS;

/// A simulated arm: takes the target it is sent, approaches, asks for its valve, holds the
/// apple once sealed, retracts, releases, and reports each phase in its `ArmState`.
struct Arm {
    state: ArmState,
    request: ValveRequest,
    apple_id: u32,
    apple_index: Option<usize>,
    phase_ticks: u32,
}

impl Arm {
    fn new(arm_id: u8) -> Self {
        Self {
            state: ArmState {
                arm_id,
                phase: PhaseCode::Idle.into(),
                ..ArmState::default()
            },
            request: ValveRequest {
                arm_id,
                kind: ValveRequestKind::Close.into(),
                ..ValveRequest::default()
            },
            apple_id: 0,
            apple_index: None,
            phase_ticks: 0,
        }
    }

    fn set_phase(&mut self, phase: PhaseCode) {
        self.state.phase = phase.into();
        self.phase_ticks = 0;
    }

    fn request(&mut self, kind: ValveRequestKind) {
        self.request.kind = kind.into();
        self.request.request_seq += 1;
    }
}

/// The tree, the camera, the valve board and the two arms.
struct Orchard {
    node: VacuumNode,
    now_ns: u64,
    apples_m: Vec<[f64; 3]>,
    picked: Vec<bool>,
    arms: [Arm; 2],
    valves: [bool; 4],
    changed_ns: [u64; 4],
    detections: Box<AppleDetections>,
    frame: u64,
    harvested: u32,
    events: u64,
}

impl Orchard {
    fn new() -> Self {
        let reach: harvest_vacuum::node::Reachability = Box::new(|arm, p, _radius| match arm {
            ArmId::Arm1 => p[1] >= -0.1,
            ArmId::Arm2 => p[1] <= 0.1,
        });
        let node = VacuumNode::new(VacuumNodeConfig::default(), reach).expect("node");
        // Three rows of six apples across both arms' sides.
        let apples_m = (0..18)
            .map(|k| {
                let (row, col) = (k / 6, k % 6);
                [
                    1.3 + 0.03 * row as f64,
                    -0.25 + 0.1 * col as f64,
                    0.25 + 0.1 * row as f64,
                ]
            })
            .collect::<Vec<_>>();
        Self {
            node,
            now_ns: 1_000 * MS,
            picked: vec![false; apples_m.len()],
            apples_m,
            arms: [Arm::new(1), Arm::new(2)],
            valves: [false, true, false, true],
            changed_ns: [0; 4],
            detections: Box::default(),
            frame: 0,
            harvested: 0,
            events: 0,
        }
    }

    /// The camera's view of the apples still on the tree (positions wobble by a few mm).
    fn see(&mut self) {
        self.frame += 1;
        let detections = &mut *self.detections;
        detections.apples.clear();
        detections.source_frame_seq = self.frame;
        detections.source_capture_ns = self.now_ns - 60 * MS;
        for (k, p) in self.apples_m.iter().enumerate() {
            if self.picked[k] {
                continue;
            }
            let wobble = 0.002 * ((self.frame + k as u64) % 3) as f64;
            let _ = detections.apples.push(AppleDetection {
                apple_id: k as u32,
                position_in_robot_m: [p[0] + wobble, p[1], p[2]],
                radius_m: 0.035,
                ..AppleDetection::default()
            });
        }
    }

    fn readings(&self) -> BoardReadings {
        let tube = |arm: usize| -> f32 {
            let inlet = 2 * arm;
            let settled = self.now_ns - self.changed_ns[inlet] >= 50 * MS;
            let held = self.arms[arm].state.phase == PhaseCode::AttachDetach
                && self.arms[arm].phase_ticks > 10;
            match (self.valves[inlet] && settled, held) {
                (true, true) => 2350.0,
                (true, false) => 800.0,
                _ => 0.0,
            }
        };
        BoardReadings {
            stamp_ns: self.now_ns,
            valve_open: self.valves,
            valve_in_transit: std::array::from_fn(|i| self.now_ns - self.changed_ns[i] < 50 * MS),
            pressure_mmh2o: [tube(0), tube(1), 2400.0],
        }
    }

    /// One tick: the node and the event conversion (what is counted), then the world.
    fn tick(&mut self) {
        let new_frame = (self.now_ns / PERIOD_NS).is_multiple_of(7);
        if new_frame {
            self.see();
        }
        let readings = self.readings();
        for arm in &mut self.arms {
            arm.state.header.capture_ns = self.now_ns;
            arm.state.header.msg_seq += 1;
        }
        let input = VacuumNodeInput {
            now_ns: self.now_ns,
            arm_states: [Some(&self.arms[0].state), Some(&self.arms[1].state)],
            valve_requests: [Some(&self.arms[0].request), Some(&self.arms[1].request)],
            readings: Some(readings),
            detections: new_frame.then_some(&*self.detections),
            emergency_stop: false,
        };
        let out = self.node.step(&input);
        let context = ArmContext {
            phase: [self.arms[0].state.phase, self.arms[1].state.phase],
            apple_id: [self.arms[0].state.apple_id, self.arms[1].state.apple_id],
        };
        for event in &out.events {
            if let Some(message) = vacuum_event(self.now_ns, event, &context) {
                std::hint::black_box(message);
                self.events += 1;
            }
        }
        let targets = out.targets;
        for (k, open) in out.valve_commands.iter().enumerate() {
            if *open != self.valves[k] {
                self.valves[k] = *open;
                self.changed_ns[k] = self.now_ns;
            }
        }

        // The arms (not the supervisor's work, but they must not allocate either).
        for (i, arm) in self.arms.iter_mut().enumerate() {
            arm.phase_ticks += 1;
            if let Some(target) = targets[i]
                && target.apple_id != 0
                && arm.state.phase == PhaseCode::Idle
            {
                arm.apple_id = target.apple_id;
                arm.apple_index = self
                    .apples_m
                    .iter()
                    .position(|p| (p[1] - target.position_in_robot_m[1]).abs() < 1e-6);
                arm.state.apple_id = target.apple_id;
                arm.set_phase(PhaseCode::Approach);
                continue;
            }
            let inlet_open = self.valves[2 * i];
            match arm.state.phase.get().ok() {
                Some(PhaseCode::Approach) if arm.phase_ticks >= 60 => {
                    arm.request(ValveRequestKind::OpenForAttach);
                    arm.set_phase(PhaseCode::AttachDetach);
                }
                Some(PhaseCode::AttachDetach) if inlet_open && arm.phase_ticks >= 40 => {
                    arm.set_phase(PhaseCode::Retract);
                }
                Some(PhaseCode::AttachDetach) if arm.phase_ticks >= 400 => {
                    // Never granted: give up.
                    arm.request(ValveRequestKind::Close);
                    arm.set_phase(PhaseCode::Retract);
                }
                Some(PhaseCode::Retract) if arm.phase_ticks >= 60 => {
                    arm.request(ValveRequestKind::Close);
                    arm.set_phase(PhaseCode::Release);
                }
                Some(PhaseCode::Release) if arm.phase_ticks >= 20 => {
                    if let Some(k) = arm.apple_index.take() {
                        self.picked[k] = true;
                        arm.state.harvested_count += 1;
                        self.harvested += 1;
                    }
                    arm.state.apple_id = 0;
                    arm.set_phase(PhaseCode::Idle);
                }
                _ => {}
            }
        }
        self.now_ns += PERIOD_NS;
    }
}

#[test]
fn a_vacuum_tick_allocates_nothing_once_running() {
    let mut orchard = Orchard::new();
    // Warm-up: the first sets, dispatches and attempts (first use of every buffer).
    for _ in 0..3000 {
        orchard.tick();
    }
    let harvested_before = orchard.harvested;
    let events_before = orchard.events;
    let ((), allocations) = allocation_counter::count_allocations(|| {
        for _ in 0..3000 {
            orchard.tick();
        }
    });
    let harvested = orchard.harvested - harvested_before;
    let events = orchard.events - events_before;
    assert!(
        harvested >= 4,
        "only {harvested} apples in the counted ticks"
    );
    assert!(events >= 10, "only {events} events in the counted ticks");
    assert_eq!(
        allocations, 0,
        "{allocations} allocations in 3000 ticks ({harvested} apples, {events} events)"
    );
}
