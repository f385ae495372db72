//! What one arm's 200 Hz tick allocates once running: `ArmNode::step` and the conversion of its
//! events into `harvest/events` messages (`ArmEventReporter::convert`), the work the arm process
//! does per tick between reading its inputs and publishing. Counted on this thread with
//! `harvest_ipc::allocation_counter` over whole pick cycles (target, approach with the clearance
//! check against the other arm, attach, twist, retract, release), a missed deadline and an
//! emergency stop, after one cycle of warm-up. Also `pick_reachable`, the kinematic test the
//! vacuum supervisor runs per apple and arm on each detection set.

use harvest_arm::harvest_events::ArmEventReporter;
use harvest_arm::node::{
    ArmNode, ArmNodeConfig, ArmNodeEvent, ArmNodeInput, EncoderSample, OtherArmInput, ServoOrder,
    pick_reachable, picking_point_m,
};
use harvest_ipc::Header;
use harvest_ipc::allocation_counter::{self, CountingAllocator};
use harvest_ipc::payloads::{
    ArmAttachment, ArmPhase as PhaseCode, ArmState, ArmTarget, VacuumState, ValveRequestKind,
};
use harvest_robot_model::ArmId;
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::kinematics::forward;
use harvest_robot_model::params::ArmParams;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const PERIOD_NS: u64 = 5_000_000;
const RADIUS_M: f64 = 0.037;
/// Apple centres arm 1 picks in turn (mid-workspace, clear of the other arm at home).
const APPLES_M: [[f64; 3]; 3] = [[1.487, -0.05, 0.50], [1.45, 0.05, 0.42], [1.50, 0.0, 0.55]];

/// Arm 1 against a plant: first-order servos tracking the set-points, a valve that takes 50 ms
/// to move, a cup that seals when open within 1.5 cm of the picking point, and arm 2 resting at
/// home (its state kept fresh).
struct Plant {
    node: ArmNode,
    reporter: ArmEventReporter,
    now_ns: u64,
    q: [f64; 4],
    v: [f64; 4],
    valve_open: bool,
    valve_changed_ns: u64,
    sealed: bool,
    apple_m: [f64; 3],
    target: Option<ArmTarget>,
    target_seq: u64,
    other: ArmState,
    emergency_stop: bool,
    harvested: u32,
    deadline_misses: u32,
}

impl Plant {
    fn new() -> Self {
        let home = ArmParams::arm1().home.to_array();
        let other_home = ArmParams::arm2().home;
        Self {
            node: ArmNode::new(ArmId::Arm1, ArmNodeConfig::default()).expect("node"),
            reporter: ArmEventReporter::new(ArmId::Arm1),
            now_ns: 10_000_000_000,
            q: home,
            v: [0.0; 4],
            valve_open: false,
            valve_changed_ns: 0,
            sealed: false,
            apple_m: APPLES_M[0],
            target: None,
            target_seq: 0,
            other: ArmState {
                arm_id: 2,
                phase: PhaseCode::Idle.into(),
                joint_position: other_home.to_array(),
                end_effector_in_robot_m: forward(&ArmParams::arm2().links, &other_home),
                ..ArmState::default()
            },
            emergency_stop: false,
            harvested: 0,
            deadline_misses: 0,
        }
    }

    fn assign(&mut self, apple_m: [f64; 3], apple_id: u32) {
        self.apple_m = apple_m;
        self.target_seq += 1;
        self.target = Some(ArmTarget {
            header: Header {
                msg_seq: self.target_seq,
                capture_ns: self.now_ns,
                publish_ns: 0,
            },
            arm_id: 1,
            apple_id,
            position_in_robot_m: apple_m,
            radius_m: RADIUS_M,
            source_capture_ns: self.now_ns - 50_000_000,
            ..ArmTarget::default()
        });
    }

    fn vacuum_state(&self) -> VacuumState {
        let in_transit = self.now_ns - self.valve_changed_ns < 50_000_000;
        let open = self.valve_open;
        let pressure = if self.sealed {
            2300.0
        } else if open && !in_transit {
            700.0
        } else if in_transit {
            600.0
        } else {
            0.0
        };
        VacuumState {
            valve_open: [u8::from(open), u8::from(!open), 0, 1],
            valve_in_transit: [u8::from(in_transit), u8::from(in_transit), 0, 0],
            pressure_mmh2o: [pressure, 0.0, 2400.0],
            arm_attachment: [
                if self.sealed {
                    ArmAttachment::Sealed
                } else if open {
                    ArmAttachment::Open
                } else {
                    ArmAttachment::Closed
                }
                .into(),
                ArmAttachment::Closed.into(),
            ],
            ..VacuumState::default()
        }
    }

    /// One tick: the node and the event conversion (what is counted), then the plant.
    fn tick(&mut self) {
        let vacuum = self.vacuum_state();
        self.other.header.capture_ns = self.now_ns;
        let input = ArmNodeInput {
            now_ns: self.now_ns,
            feedback: Some(EncoderSample {
                capture_ns: self.now_ns,
                position: self.q,
                velocity: self.v,
            }),
            target: self.target.as_ref(),
            vacuum: Some(&vacuum),
            grant: None,
            other_arm: Some(OtherArmInput {
                state: &self.other,
                target: None,
            }),
            emergency_stop: self.emergency_stop,
        };
        let out = self.node.step(&input);
        let phase = out.state.phase.get().unwrap_or(PhaseCode::Idle);
        for event in &out.events {
            if let Some(message) =
                self.reporter
                    .convert(self.now_ns, phase, event, self.target.as_ref())
            {
                std::hint::black_box(message);
            }
            match event {
                ArmNodeEvent::AttemptEnded {
                    harvested: true, ..
                } => self.harvested += 1,
                ArmNodeEvent::Cycle(harvest_arm::picking_cycle::CycleEvent::DeadlineMissed {
                    ..
                }) => self.deadline_misses += 1,
                _ => {}
            }
        }
        self.reporter.end_tick();
        let order = out.servo;
        let open = out.valve_request.kind == ValveRequestKind::OpenForAttach;
        // The plant (not the arm's work, but it must not allocate either).
        if open != self.valve_open {
            self.valve_open = open;
            self.valve_changed_ns = self.now_ns;
        }
        for k in 0..5 {
            let t = k as f64 * 1e-3;
            let command: [f64; 4] = match order {
                ServoOrder::Hold => [0.0; 4],
                ServoOrder::Track { position, velocity } => std::array::from_fn(|j| {
                    velocity[j] + 20.0 * (position[j] + velocity[j] * t - self.q[j])
                }),
            };
            let blend = 1.0 - (-1e-3f64 / 0.02).exp();
            for ((v, q), c) in self.v.iter_mut().zip(self.q.iter_mut()).zip(command) {
                *v += (c - *v) * blend;
                *q += *v * 1e-3;
            }
        }
        let ee = forward(&ArmParams::arm1().links, &JointPosition::from_array(self.q));
        let pick = picking_point_m(self.apple_m, RADIUS_M, 0.0);
        let near = (0..3)
            .map(|i| (ee[i] - pick[i]).powi(2))
            .sum::<f64>()
            .sqrt()
            < 0.015;
        if self.valve_open && self.now_ns - self.valve_changed_ns >= 50_000_000 && near {
            self.sealed = true;
        }
        if !self.valve_open {
            self.sealed = false;
        }
        self.now_ns += PERIOD_NS;
    }

    /// Runs until `harvested` apples were released, at most `max_ticks`.
    fn run_until_harvested(&mut self, harvested: u32, max_ticks: u32) {
        for _ in 0..max_ticks {
            if self.harvested >= harvested {
                return;
            }
            self.tick();
        }
        panic!(
            "only {} of {harvested} apples harvested in {max_ticks} ticks",
            self.harvested
        );
    }
}

#[test]
fn an_arm_tick_allocates_nothing_once_running() {
    let mut plant = Plant::new();
    // Warm-up: one whole cycle (first use of every buffer).
    plant.tick();
    plant.assign(APPLES_M[0], 1);
    plant.run_until_harvested(1, 4000);
    for _ in 0..50 {
        plant.tick();
    }

    let ((), allocations) = allocation_counter::count_allocations(|| {
        // Two more cycles, the second with a missed deadline during the approach.
        plant.assign(APPLES_M[1], 2);
        plant.run_until_harvested(2, 4000);
        for _ in 0..20 {
            plant.tick();
        }
        plant.assign(APPLES_M[2], 3);
        for _ in 0..100 {
            plant.tick();
        }
        plant.now_ns += 4 * PERIOD_NS;
        plant.run_until_harvested(3, 4000);
        // An emergency stop during the next approach, and its release.
        plant.assign(APPLES_M[0], 4);
        for _ in 0..100 {
            plant.tick();
        }
        plant.emergency_stop = true;
        for _ in 0..20 {
            plant.tick();
        }
        plant.emergency_stop = false;
        for _ in 0..20 {
            plant.tick();
        }
        // The vacuum supervisor's reachability test of each apple for both arms.
        let config = ArmNodeConfig::default();
        for apple_m in APPLES_M {
            for arm in [ArmId::Arm1, ArmId::Arm2] {
                std::hint::black_box(pick_reachable(arm, apple_m, RADIUS_M, &config));
            }
        }
    });
    assert_eq!(plant.harvested, 3);
    assert_eq!(plant.deadline_misses, 1);
    assert_eq!(
        allocations, 0,
        "{allocations} allocations in the counted ticks"
    );
}
