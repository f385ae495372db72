use super::*;
use crate::policy::{CloseReason, PolicyKind, RefuseReason};
use crate::replan::AttemptResult;
use harvest_ipc::WireCode;
use harvest_ipc::payloads::arm::TargetStatus;
use harvest_ipc::payloads::{
    AppleDetection, AppleDetections, ArmPhase as PhaseCode, ArmState, ArmTarget, ValveRequest,
    ValveRequestKind,
};
use harvest_ipc::payloads::{ArmAttachment, VacuumPolicyCode};

const MS: u64 = 1_000_000;
const LEFT: [f64; 3] = [1.3, 0.15, 0.3];
const RIGHT: [f64; 3] = [1.3, -0.15, 0.3];

/// Arm 1 reaches y >= -0.1, arm 2 y <= 0.1 (robot frame, arm 1 on +y).
fn reach() -> Reachability {
    Box::new(|arm, p, _radius| match arm {
        ArmId::Arm1 => p[1] >= -0.1,
        ArmId::Arm2 => p[1] <= 0.1,
    })
}

fn node(policy: PolicyKind) -> VacuumNode {
    VacuumNode::new(
        VacuumNodeConfig {
            policy,
            ..VacuumNodeConfig::default()
        },
        reach(),
    )
    .expect("node")
}

fn detections(capture_ns: u64, positions: &[[f64; 3]]) -> AppleDetections {
    let mut set = AppleDetections {
        source_capture_ns: capture_ns,
        ..AppleDetections::default()
    };
    for (k, p) in positions.iter().enumerate() {
        let pushed = set.apples.push(AppleDetection {
            apple_id: k as u32,
            position_in_robot_m: *p,
            radius_m: 0.035,
            ..AppleDetection::default()
        });
        assert!(pushed.is_ok());
    }
    set
}

/// Both arms, the board and the clock, driven by hand.
struct Bench {
    node: VacuumNode,
    now_ns: u64,
    states: [ArmState; 2],
    requests: [ValveRequest; 2],
    /// Board: commanded valves (from the node's outputs) and when each changed.
    valves: [bool; 4],
    changed_ns: [u64; 4],
    travel_ns: u64,
    /// Arm tube vacuum, mmH2O (set by the test), and the source.
    pressure: [f32; 3],
    estop: bool,
    events: Vec<VacuumNodeEvent>,
}

impl Bench {
    fn new(policy: PolicyKind) -> Self {
        let state = |arm_id| ArmState {
            arm_id,
            phase: PhaseCode::Idle.into(),
            ..ArmState::default()
        };
        let request = |arm_id| ValveRequest {
            arm_id,
            kind: ValveRequestKind::Close.into(),
            ..ValveRequest::default()
        };
        Self {
            node: node(policy),
            now_ns: 1_000 * MS,
            states: [state(1), state(2)],
            requests: [request(1), request(2)],
            valves: [false, true, false, true],
            changed_ns: [0; 4],
            travel_ns: 50 * MS,
            pressure: [0.0, 0.0, 2400.0],
            estop: false,
            events: Vec::new(),
        }
    }

    fn readings(&self) -> BoardReadings {
        BoardReadings {
            stamp_ns: self.now_ns,
            valve_open: self.valves,
            valve_in_transit: std::array::from_fn(|i| {
                self.now_ns - self.changed_ns[i] < self.travel_ns
            }),
            pressure_mmh2o: self.pressure,
        }
    }

    fn tick_with(&mut self, set: Option<&AppleDetections>) -> VacuumNodeOutput {
        let input = VacuumNodeInput {
            now_ns: self.now_ns,
            arm_states: [Some(&self.states[0]), Some(&self.states[1])],
            valve_requests: [Some(&self.requests[0]), Some(&self.requests[1])],
            readings: Some(self.readings()),
            detections: set,
            emergency_stop: self.estop,
        };
        let out = self.node.step(&input).clone();
        for (i, open) in out.valve_commands.iter().enumerate() {
            if *open != self.valves[i] {
                self.valves[i] = *open;
                self.changed_ns[i] = self.now_ns;
            }
        }
        self.events.extend(out.events.iter().cloned());
        self.now_ns += 5 * MS;
        out
    }

    fn tick(&mut self) -> VacuumNodeOutput {
        self.tick_with(None)
    }

    fn ticks(&mut self, n: usize) {
        for _ in 0..n {
            self.tick();
        }
    }

    fn set_phase(&mut self, arm: usize, phase: PhaseCode, apple_id: u32) {
        self.states[arm].phase.set(phase);
        self.states[arm].apple_id = apple_id;
    }

    fn request(&mut self, arm: usize, kind: ValveRequestKind) {
        self.requests[arm].kind.set(kind);
        self.requests[arm].request_seq += 1;
    }

    fn count(&self, f: impl Fn(&VacuumNodeEvent) -> bool) -> usize {
        self.events.iter().filter(|e| f(e)).count()
    }
}

#[test]
fn apples_are_dispatched_one_per_tick_with_wire_ids_and_radius() {
    let mut b = Bench::new(PolicyKind::V2024);
    let set = detections(b.now_ns - 100 * MS, &[LEFT, RIGHT]);
    let first = b.tick_with(Some(&set));
    let second = b.tick();
    let dispatched: Vec<ArmTarget> = first
        .targets
        .iter()
        .chain(second.targets.iter())
        .flatten()
        .copied()
        .collect();
    assert_eq!(dispatched.len(), 2);
    assert_eq!(first.targets.iter().flatten().count(), 1);
    for t in &dispatched {
        let expected = if t.arm_id == 1 { LEFT } else { RIGHT };
        assert_eq!(t.position_in_robot_m, expected);
        assert_eq!(t.radius_m, 0.035);
        assert_eq!(t.source_capture_ns, set.source_capture_ns);
        assert!(t.apple_id >= 1, "wire ids start at 1");
    }
    assert_ne!(dispatched[0].header.msg_seq, dispatched[1].header.msg_seq);
    // Nothing more to dispatch.
    assert!(b.tick().targets.iter().all(Option::is_none));
}

#[test]
fn the_baseline_lets_one_arm_out_at_a_time() {
    let mut b = Bench::new(PolicyKind::Baseline);
    let set = detections(b.now_ns, &[LEFT, RIGHT]);
    let out = b.tick_with(Some(&set));
    let target = out.targets[0].expect("arm 1 first");
    b.ticks(3);
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::ApproachRefused {
                arm: ArmId::Arm2,
                reason: RefuseReason::OtherArmActive { .. }
            }
        )),
        1
    );
    // Arm 1 runs its cycle and ends it with a harvest; then arm 2 goes.
    b.set_phase(0, PhaseCode::Approach, target.apple_id);
    b.tick();
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::AttemptStarted {
                arm: ArmId::Arm1,
                ..
            }
        )),
        1
    );
    b.set_phase(0, PhaseCode::Idle, 0);
    b.states[0].harvested_count = 1;
    let out = b.tick();
    assert!(b.events.iter().any(|e| matches!(
        e,
        VacuumNodeEvent::AttemptFinished {
            arm: ArmId::Arm1,
            result: AttemptResult::Harvested,
            ..
        }
    )));
    assert!(out.targets[1].is_some());
    assert!(b.node.planner().queue(ArmId::Arm1).is_empty());
}

#[test]
fn a_target_not_taken_up_is_refreshed_then_given_up() {
    let mut b = Bench::new(PolicyKind::V2024);
    let set = detections(b.now_ns, &[LEFT]);
    let first = b.tick_with(Some(&set)).targets[0].expect("dispatched");
    b.ticks(10);
    let fresh = detections(b.now_ns, &[[LEFT[0] + 0.005, LEFT[1], LEFT[2]]]);
    let out = b.tick_with(Some(&fresh));
    let refreshed = out.targets[0].expect("refreshed");
    assert_eq!(refreshed.apple_id, first.apple_id);
    assert_eq!(refreshed.position_in_robot_m, first.position_in_robot_m);
    assert!(refreshed.header.msg_seq > first.header.msg_seq);
    assert_eq!(refreshed.source_capture_ns, fresh.source_capture_ns);
    b.ticks(600);
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::DispatchTimedOut {
                arm: ArmId::Arm1,
                ..
            }
        )),
        1
    );
}

#[test]
fn failure_aware_policy_staggers_attempts_and_closes_a_failure_in_the_same_tick() {
    let mut b = Bench::new(PolicyKind::V2024);
    // Both arms at their apples asking for the vacuum.
    b.set_phase(0, PhaseCode::AttachDetach, 1);
    b.set_phase(1, PhaseCode::AttachDetach, 2);
    b.request(0, ValveRequestKind::OpenForAttach);
    b.request(1, ValveRequestKind::OpenForAttach);
    let out = b.tick();
    assert_eq!(out.valve_commands, [true, false, false, true]);
    assert_eq!(out.grants[0].map(|g| g.granted), Some(1));
    let refusal = out.grants[1].expect("answer to arm 2");
    assert_eq!((refusal.granted, refusal.reason), (0, 5));
    // The gate travels; then arm 1 seals (its tube reaches the source).
    b.ticks(10);
    b.pressure = [2350.0, 0.0, 2400.0];
    b.ticks(3);
    assert_eq!(
        b.node.attachment(ArmId::Arm1),
        AttachmentState::OpenToAtmosphere
    );
    b.ticks(5);
    assert_eq!(b.node.attachment(ArmId::Arm1), AttachmentState::Sealed);
    // Arm 2 is granted once arm 1 is sealed; the refusal was reported once.
    assert!(b.valves[2]);
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::ValveRefused {
                arm: ArmId::Arm2,
                ..
            }
        )),
        1
    );
    // Arm 2's cup never seals: 250 ms after its gate arrived the failure closes it at once.
    b.pressure = [2350.0, 700.0, 2000.0];
    let mut closed_with_failure = false;
    for _ in 0..100 {
        let out = b.tick();
        let failed = out.events.iter().any(|e| {
            matches!(e, VacuumNodeEvent::Attachment(c) if c.arm == ArmId::Arm2
                && c.to == AttachmentState::AttachFailed)
        });
        if failed {
            assert!(!out.valve_commands[2], "closed in the tick of the failure");
            assert!(out.events.iter().any(|e| matches!(
                e,
                VacuumNodeEvent::ValveClosed {
                    arm: ArmId::Arm2,
                    cause: ValveCloseCause::Policy(CloseReason::AttachFailed)
                }
            )));
            closed_with_failure = true;
            break;
        }
    }
    assert!(closed_with_failure);
    // The standing request is not granted a second time.
    b.ticks(50);
    assert!(!b.valves[2]);
    assert_eq!(
        b.count(|e| matches!(e, VacuumNodeEvent::ValveOpened { arm: ArmId::Arm2 })),
        1
    );
    // Arm 1 reaches the drop-off and asks to close: released.
    b.set_phase(0, PhaseCode::Release, 1);
    b.request(0, ValveRequestKind::Close);
    let out = b.tick();
    assert!(!out.valve_commands[0] && out.valve_commands[1]);
}

#[test]
fn the_2023_policy_holds_the_vacuum_until_the_other_release_is_done() {
    let mut b = Bench::new(PolicyKind::V2023);
    b.set_phase(0, PhaseCode::Retract, 1);
    b.set_phase(1, PhaseCode::AttachDetach, 2);
    b.request(1, ValveRequestKind::OpenForAttach);
    let out = b.tick();
    assert_eq!(out.grants[1].map(|g| (g.granted, g.reason)), Some((0, 7)));
    b.set_phase(0, PhaseCode::Release, 1);
    b.ticks(5);
    assert!(!b.valves[2]);
    b.set_phase(0, PhaseCode::Idle, 0);
    let out = b.tick();
    assert!(out.valve_commands[2]);
    assert_eq!(out.grants[1].map(|g| g.granted), Some(1));
}

#[test]
fn emergency_stop_closes_every_valve_and_stops_dispatching() {
    let mut b = Bench::new(PolicyKind::V2024);
    b.set_phase(0, PhaseCode::AttachDetach, 1);
    b.request(0, ValveRequestKind::OpenForAttach);
    b.tick();
    assert!(b.valves[0]);
    b.estop = true;
    let out = b.tick();
    assert!(out.close_all);
    assert_eq!(out.valve_commands, [false; 4]);
    assert!(
        out.events
            .contains(&VacuumNodeEvent::EmergencyStop { engaged: true })
    );
    assert!(out.events.contains(&VacuumNodeEvent::ValveClosed {
        arm: ArmId::Arm1,
        cause: ValveCloseCause::EmergencyStop
    }));
    // Engaged: no valve opens, no apple is dispatched.
    b.request(0, ValveRequestKind::OpenForAttach);
    b.set_phase(1, PhaseCode::Idle, 0);
    let set = detections(b.now_ns, &[RIGHT]);
    let out = b.tick_with(Some(&set));
    assert!(!out.close_all, "close_all only on the engaging tick");
    assert_eq!(out.valve_commands, [false; 4]);
    assert!(out.targets.iter().all(Option::is_none));
    b.estop = false;
    b.set_phase(0, PhaseCode::Idle, 0);
    let out = b.tick();
    assert!(
        out.events
            .contains(&VacuumNodeEvent::EmergencyStop { engaged: false })
    );
    assert_eq!(out.valve_commands, [false, true, false, true]);
    assert!(out.targets[1].is_some());
}

#[test]
fn an_apple_failed_max_attempts_times_is_given_up_even_under_new_ids() {
    let mut b = Bench::new(PolicyKind::V2024);
    let max = VacuumNodeConfig::default().planner.max_attempts;
    for attempt in 0..max {
        // Each set sees the apple up to 4 cm off: the planner loses its identity (3 cm match).
        let offset = if attempt % 2 == 0 { 0.02 } else { -0.02 };
        let p = [LEFT[0] + offset, LEFT[1], LEFT[2]];
        b.tick_with(Some(&detections(b.now_ns, &[])));
        let out = b.tick_with(Some(&detections(b.now_ns, &[p])));
        let target = out.targets[0].expect("dispatched");
        b.set_phase(0, PhaseCode::Approach, target.apple_id);
        b.tick();
        b.set_phase(0, PhaseCode::Idle, 0);
        b.tick();
    }
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::AttemptFinished {
                result: AttemptResult::Failed,
                ..
            }
        )),
        max as usize
    );
    let out = b.tick_with(Some(&detections(
        b.now_ns,
        &[[LEFT[0] + 0.03, LEFT[1], LEFT[2]]],
    )));
    assert!(out.targets.iter().all(Option::is_none));
    assert!(
        out.events
            .iter()
            .any(|e| matches!(e, VacuumNodeEvent::Replanned { given_up: 1, .. }))
    );
    assert!(b.node.is_idle());
}

#[test]
fn a_disabled_arm_gets_no_apple_and_no_vacuum() {
    let mut node = VacuumNode::new(
        VacuumNodeConfig {
            arms_enabled: [true, false],
            ..VacuumNodeConfig::default()
        },
        reach(),
    )
    .expect("node");
    let idle = |arm_id| ArmState {
        arm_id,
        ..ArmState::default()
    };
    let (s1, s2) = (idle(1), idle(2));
    let open2 = ValveRequest {
        arm_id: 2,
        kind: ValveRequestKind::OpenForAttach.into(),
        request_seq: 1,
        ..ValveRequest::default()
    };
    let set = detections(0, &[RIGHT, [1.3, -0.3, 0.3]]);
    let out = node
        .step(&VacuumNodeInput {
            now_ns: 5 * MS,
            arm_states: [Some(&s1), Some(&s2)],
            valve_requests: [None, Some(&open2)],
            readings: None,
            detections: Some(&set),
            emergency_stop: false,
        })
        .clone();
    assert!(out.targets.iter().all(Option::is_none));
    assert_eq!(
        out.grants[1].map(|g| (g.granted, g.reason)),
        Some((0, REFUSED_ARM_DISABLED))
    );
    assert_eq!(out.valve_commands, [false, true, false, true]);
    assert!(node.planner().queue(ArmId::Arm2).is_empty());
    assert!(node.is_idle());
}

#[test]
fn the_published_state_mirrors_the_board_and_the_inference() {
    let mut b = Bench::new(PolicyKind::V2023);
    let out = b.tick();
    assert_eq!(out.state.policy, VacuumPolicyCode::Policy2023);
    assert_eq!(out.state.valve_open, [0, 1, 0, 1]);
    assert_eq!(out.state.pressure_mmh2o, [0.0, 0.0, 2400.0]);
    assert_eq!(
        out.state.arm_attachment,
        [WireCode::new(ArmAttachment::Closed); 2]
    );
    b.set_phase(0, PhaseCode::AttachDetach, 1);
    b.request(0, ValveRequestKind::OpenForAttach);
    b.tick();
    let out = b.tick();
    // The board reports the gate moving; the inference waits for it.
    assert_eq!(out.state.valve_open, [1, 0, 0, 1]);
    assert_eq!(out.state.valve_in_transit, [1, 1, 0, 0]);
    assert_eq!(
        out.state.arm_attachment,
        [WireCode::new(ArmAttachment::Closed); 2]
    );
    b.pressure = [2350.0, 0.0, 2400.0];
    b.ticks(20);
    let out = b.tick();
    assert_eq!(
        out.state.arm_attachment,
        [
            WireCode::new(ArmAttachment::Sealed),
            WireCode::new(ArmAttachment::Closed)
        ]
    );
    assert_eq!(policy_code(PolicyKind::V2024), VacuumPolicyCode::Policy2024);
    assert_eq!(
        attachment_code(AttachmentState::Dropped),
        ArmAttachment::Open
    );
}

#[test]
fn config_is_checked() {
    let bad = VacuumNodeConfig {
        dispatch_timeout_s: 0.0,
        ..VacuumNodeConfig::default()
    };
    assert!(matches!(
        VacuumNode::new(bad, reach()),
        Err(VacuumNodeError::DispatchTimeout(_))
    ));
    let bad = VacuumNodeConfig {
        give_up_radius_m: f64::NAN,
        ..VacuumNodeConfig::default()
    };
    assert!(matches!(
        VacuumNode::new(bad, reach()),
        Err(VacuumNodeError::GiveUpRadius(_))
    ));
    let bad = VacuumNodeConfig {
        held_margin_m: -0.01,
        ..VacuumNodeConfig::default()
    };
    assert!(matches!(
        VacuumNode::new(bad, reach()),
        Err(VacuumNodeError::HeldMargin(_))
    ));
}

#[test]
fn a_detection_at_a_holding_arm_cup_is_not_a_tree_apple() {
    // Arm 1's cup on the robot-facing surface of the apple at LEFT (radius 3.5 cm), a
    // neighbour touching that apple on its side.
    let cup = [LEFT[0] - 0.035, LEFT[1], LEFT[2]];
    let neighbour = [LEFT[0], LEFT[1] + 0.07, LEFT[2]];
    let run = |phase: PhaseCode, holding: u8| {
        let mut b = Bench::new(PolicyKind::V2024);
        b.set_phase(0, phase, 0);
        b.states[0].holding = holding;
        b.states[0].end_effector_in_robot_m = cup;
        let set = detections(b.now_ns, &[LEFT, neighbour]);
        b.tick_with(Some(&set));
        let held = b
            .events
            .iter()
            .find_map(|e| match e {
                VacuumNodeEvent::Replanned { summary, .. } => Some(summary.held),
                _ => None,
            })
            .expect("re-planned");
        let mut queued: Vec<[f64; 3]> = b
            .node
            .planner()
            .queue(ArmId::Arm1)
            .iter()
            .map(|a| a.position_m)
            .collect();
        queued.sort_by(|a, b| a[1].total_cmp(&b[1]));
        (held, queued)
    };
    // Holding (attached and detaching), or retracting / releasing: the apple at the cup is the
    // one in hand; the neighbour is still a tree apple.
    for (phase, holding) in [
        (PhaseCode::AttachDetach, 1),
        (PhaseCode::Retract, 1),
        (PhaseCode::Retract, 0),
        (PhaseCode::Release, 0),
    ] {
        assert_eq!(
            run(phase, holding),
            (1, vec![neighbour]),
            "{phase:?} {holding}"
        );
    }
    // At the apple without holding it (the attachment failed, or not tried yet): both are on
    // the tree and both are assigned.
    for phase in [PhaseCode::AttachDetach, PhaseCode::Approach] {
        assert_eq!(run(phase, 0), (0, vec![LEFT, neighbour]), "{phase:?}");
    }
}

/// The bench's arm `arm` reports its target `apple_id` refused (waiting or for good).
fn report_target(b: &mut Bench, arm: usize, status: TargetStatus, apple_id: u32) {
    b.states[arm].target_status.set(status);
    b.states[arm].target_apple_id = apple_id;
}

#[test]
fn a_target_the_arm_keeps_waiting_on_goes_to_the_other_arm() {
    // Between the arms: both reach it; arm 1 gets it while arm 2 is busy elsewhere.
    let shared = [1.3, 0.05, 0.3];
    let mut b = Bench::new(PolicyKind::V2024);
    b.set_phase(1, PhaseCode::Approach, 0);
    let set = detections(b.now_ns, &[shared]);
    let target = b.tick_with(Some(&set)).targets[0].expect("dispatched to arm 1");
    // Arm 1 waits: the other arm's path is in the way. Kept until the patience is over.
    report_target(&mut b, 0, TargetStatus::Waiting, target.apple_id);
    let patience_ticks = (0.25e9 / (5 * MS) as f64) as usize;
    b.ticks(patience_ticks - 2);
    assert_eq!(
        b.count(|e| matches!(e, VacuumNodeEvent::TargetWithdrawn { .. })),
        0
    );
    let mut withdrawal = None;
    for _ in 0..4 {
        let out = b.tick();
        withdrawal = withdrawal.or(out.targets[0]);
    }
    let withdrawal = withdrawal.expect("withdrawal published");
    assert_eq!(withdrawal.apple_id, 0);
    assert!(withdrawal.position_in_robot_m.iter().all(|c| c.is_nan()));
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::TargetWithdrawn {
                arm: ArmId::Arm1,
                to: ArmId::Arm2,
                ..
            }
        )),
        1
    );
    // Not an attempt; queued for arm 2, and a new detection set does not hand it back.
    let apple = b.node.planner().queue(ArmId::Arm2)[0];
    assert_eq!(wire_id(apple.id), target.apple_id);
    assert_eq!(b.node.planner().attempts(apple.id), 0);
    report_target(&mut b, 0, TargetStatus::None, 0);
    b.tick_with(Some(&detections(b.now_ns, &[shared])));
    assert!(b.node.planner().queue(ArmId::Arm1).is_empty());
    b.ticks(10);
    assert!(
        b.node.planner().queue(ArmId::Arm1).is_empty(),
        "no rebalancing back"
    );
    // Arm 2 free: it takes the apple at once.
    b.set_phase(1, PhaseCode::Idle, 0);
    let out = b.tick();
    let to_arm2 = out.targets[1].expect("dispatched to arm 2");
    assert_eq!(to_arm2.apple_id, target.apple_id);
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::DispatchTimedOut { .. } | VacuumNodeEvent::TargetRefused { .. }
        )),
        0
    );
}

#[test]
fn a_waiting_arm_with_nowhere_else_to_send_its_apple_keeps_it_and_a_refusal_ends_at_once() {
    // Arm 1 only (LEFT), nothing else queued: the arm keeps retrying until the timeout.
    let mut b = Bench::new(PolicyKind::V2024);
    let set = detections(b.now_ns, &[LEFT]);
    let target = b.tick_with(Some(&set)).targets[0].expect("dispatched");
    report_target(&mut b, 0, TargetStatus::Waiting, target.apple_id);
    b.ticks(700);
    assert_eq!(
        b.count(|e| matches!(e, VacuumNodeEvent::TargetWithdrawn { .. })),
        0
    );
    assert_eq!(
        b.count(|e| matches!(e, VacuumNodeEvent::DispatchTimedOut { .. })),
        1
    );
    // Dispatched again (the next set still sees it).
    let target =
        b.tick_with(Some(&detections(b.now_ns, &[LEFT]))).targets[0].expect("dispatched again");
    report_target(&mut b, 0, TargetStatus::None, 0);
    b.tick();
    // A status about another apple (an older target) is not about this one.
    report_target(&mut b, 0, TargetStatus::Refused, target.apple_id + 7);
    b.tick();
    assert_eq!(
        b.count(|e| matches!(e, VacuumNodeEvent::TargetRefused { .. })),
        0
    );
    // Refused for good: the attempt ends as failed at once, without the 3 s timeout.
    report_target(&mut b, 0, TargetStatus::Refused, target.apple_id);
    b.tick();
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::TargetRefused {
                arm: ArmId::Arm1,
                ..
            }
        )),
        1
    );
    assert!(b.node.planner().in_progress(ArmId::Arm1).is_none());
    b.ticks(700);
    assert_eq!(
        b.count(|e| matches!(e, VacuumNodeEvent::DispatchTimedOut { .. })),
        1,
        "only the first one"
    );
}

// --- Operator: dispatch held per arm.

#[test]
fn a_held_arm_gets_no_target_until_released() {
    let mut b = Bench::new(PolicyKind::V2024);
    b.node.hold_dispatch([true, true]);
    let set = detections(b.now_ns - 100 * MS, &[LEFT, RIGHT]);
    assert!(b.tick_with(Some(&set)).targets.iter().all(Option::is_none));
    for _ in 0..10 {
        assert!(b.tick().targets.iter().all(Option::is_none));
    }
    // Arm 2 only: the right apple goes out, the left one stays queued.
    b.node.hold_dispatch([true, false]);
    let out = b.tick();
    let dispatched: Vec<ArmTarget> = out.targets.iter().flatten().copied().collect();
    assert_eq!(dispatched.len(), 1);
    assert_eq!(dispatched[0].arm_id, 2);
    assert!(b.tick().targets[0].is_none());
    b.node.hold_dispatch([false, false]);
    let out = b.tick();
    assert_eq!(out.targets[0].map(|t| t.position_in_robot_m), Some(LEFT));
}

/// One attempt of arm 1 on an apple at `LEFT`: dispatched, taken up, the valve granted, the cup
/// sealed at `sealed_mmh2o` (source at `source_mmh2o`), then the seal lost with the valve
/// still open (the fruit slipped off), the arm idle again.
fn slip_once(b: &mut Bench, sealed_mmh2o: f32, source_mmh2o: f32) {
    b.tick_with(Some(&detections(b.now_ns, &[])));
    let out = b.tick_with(Some(&detections(b.now_ns, &[LEFT])));
    let target = out.targets[0].expect("dispatched");
    b.set_phase(0, PhaseCode::Approach, target.apple_id);
    b.tick();
    b.set_phase(0, PhaseCode::AttachDetach, target.apple_id);
    b.request(0, ValveRequestKind::OpenForAttach);
    b.ticks(12);
    b.pressure = [sealed_mmh2o, 0.0, source_mmh2o];
    b.ticks(10);
    assert_eq!(b.node.attachment(ArmId::Arm1), AttachmentState::Sealed);
    b.pressure = [100.0, 0.0, source_mmh2o];
    b.ticks(10);
    assert!(b.events.iter().any(|e| matches!(
        e,
        VacuumNodeEvent::Attachment(c) if c.arm == ArmId::Arm1
            && c.from == AttachmentState::Sealed
            && c.to == AttachmentState::Dropped
    )));
    b.request(0, ValveRequestKind::Close);
    b.set_phase(0, PhaseCode::Idle, 0);
    b.ticks(12);
    b.pressure = [0.0, 0.0, 2400.0];
}

#[test]
fn an_apple_that_slipped_at_full_vacuum_is_given_up_at_once() {
    let mut b = Bench::new(PolicyKind::V2024);
    slip_once(&mut b, 2350.0, 2400.0);
    assert_eq!(
        b.count(|e| matches!(
            e,
            VacuumNodeEvent::AttemptFinished {
                result: AttemptResult::Failed,
                ..
            }
        )),
        1
    );
    let out = b.tick_with(Some(&detections(b.now_ns, &[LEFT])));
    assert!(out.targets.iter().all(Option::is_none));
    assert!(
        out.events
            .iter()
            .any(|e| matches!(e, VacuumNodeEvent::Replanned { given_up: 1, .. }))
    );
}

#[test]
fn an_apple_that_slipped_with_the_vacuum_sagged_is_tried_again() {
    let mut b = Bench::new(PolicyKind::V2024);
    // The source sagged (the other cup open): the arm sealed at 1450 mmH2O, about 27 N.
    slip_once(&mut b, 1450.0, 1500.0);
    let out = b.tick_with(Some(&detections(b.now_ns, &[LEFT])));
    assert!(out.targets[0].is_some(), "a second attempt is dispatched");
    // Off: every slip is retried up to `max_attempts`.
    let mut b = Bench::new(PolicyKind::V2024);
    b.node = VacuumNode::new(
        VacuumNodeConfig {
            slip_give_up_vacuum_mmh2o: 0.0,
            ..VacuumNodeConfig::default()
        },
        reach(),
    )
    .expect("node");
    slip_once(&mut b, 2350.0, 2400.0);
    let out = b.tick_with(Some(&detections(b.now_ns, &[LEFT])));
    assert!(out.targets[0].is_some());
    assert!(matches!(
        VacuumNode::new(
            VacuumNodeConfig {
                slip_give_up_vacuum_mmh2o: f32::NAN,
                ..VacuumNodeConfig::default()
            },
            reach()
        ),
        Err(VacuumNodeError::SlipGiveUpVacuum(_))
    ));
}
