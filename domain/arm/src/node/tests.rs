use super::*;
use harvest_ipc::WireCode;
use harvest_ipc::payloads::arm::TargetStatus;
use harvest_robot_model::kinematics::inverse;

/// The attachment the vacuum supervisor would infer for a line open or not, sealed or not.
fn attachment(sealed: bool, open: bool) -> WireCode<ArmAttachment> {
    match (sealed, open) {
        (true, _) => ArmAttachment::Sealed,
        (false, true) => ArmAttachment::Open,
        (false, false) => ArmAttachment::Closed,
    }
    .into()
}

const PERIOD_NS: u64 = 5_000_000;
/// A mid-workspace apple centre of arm 1 (its picking point is 0.52 m from the home cup).
const APPLE_M: [f64; 3] = [1.487, -0.05, 0.50];
const RADIUS_M: f64 = 0.037;

/// One arm node against a plant: first-order servos with the drive law of the simulator
/// (position loop with feed-forward), a valve that takes `valve_travel_ns` to move, and a cup
/// that seals when open within 1.5 cm of the picking point.
struct Bench {
    node: ArmNode,
    now_ns: u64,
    q: [f64; 4],
    v: [f64; 4],
    order: ServoOrder,
    order_ns: u64,
    valve_commanded_open: bool,
    valve_changed_ns: u64,
    valve_travel_ns: u64,
    vacuum_follows_requests: bool,
    sealed: bool,
    target: Option<ArmTarget>,
    other: Option<ArmState>,
    emergency_stop: bool,
    grant: Option<ValveGrant>,
    events: Vec<(u64, ArmNodeEvent)>,
    outputs: Vec<ArmNodeOutput>,
}

impl Bench {
    fn new(config: ArmNodeConfig) -> Self {
        Self {
            node: ArmNode::new(ArmId::Arm1, config).expect("node"),
            now_ns: 10_000_000_000,
            q: [0.0; 4],
            v: [0.0; 4],
            order: ServoOrder::Hold,
            order_ns: 0,
            valve_commanded_open: false,
            valve_changed_ns: 0,
            valve_travel_ns: 50_000_000,
            vacuum_follows_requests: true,
            sealed: false,
            target: None,
            other: None,
            emergency_stop: false,
            grant: None,
            events: Vec::new(),
            outputs: Vec::new(),
        }
    }

    fn single_arm() -> Self {
        Self::new(ArmNodeConfig {
            other_arm_present: false,
            ..ArmNodeConfig::default()
        })
    }

    fn vacuum_state(&self) -> VacuumState {
        let in_transit = self.now_ns - self.valve_changed_ns < self.valve_travel_ns;
        let open = self.valve_commanded_open;
        let settled_open = open && !in_transit;
        let pressure = if self.sealed {
            2300.0
        } else if settled_open {
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
            arm_attachment: [attachment(self.sealed, open), ArmAttachment::Closed.into()],
            ..VacuumState::default()
        }
    }

    fn tick(&mut self) -> ArmNodeOutput {
        let vacuum = self.vacuum_state();
        let input = ArmNodeInput {
            now_ns: self.now_ns,
            feedback: Some(EncoderSample {
                capture_ns: self.now_ns,
                position: self.q,
                velocity: self.v,
            }),
            target: self.target.as_ref(),
            vacuum: Some(&vacuum),
            grant: self.grant.as_ref(),
            other_arm: self.other.as_ref().map(|state| OtherArmInput {
                state,
                target: None,
            }),
            emergency_stop: self.emergency_stop,
        };
        let out = self.node.step(&input).clone();
        for e in &out.events {
            self.events.push((self.now_ns, e.clone()));
        }
        self.order = out.servo;
        self.order_ns = self.now_ns;
        if self.vacuum_follows_requests {
            let open = out.valve_request.kind == ValveRequestKind::OpenForAttach;
            if open != self.valve_commanded_open {
                self.valve_commanded_open = open;
                self.valve_changed_ns = self.now_ns;
            }
        }
        // Plant: 5 sub-steps of 1 ms.
        for k in 0..5 {
            let t = k as f64 * 1e-3;
            let command: [f64; 4] = match self.order {
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
        let pick = picking_point_m(APPLE_M, RADIUS_M, 0.0);
        let near = (0..3)
            .map(|i| (ee[i] - pick[i]).powi(2))
            .sum::<f64>()
            .sqrt()
            < 0.015;
        let settled_open = self.valve_commanded_open
            && self.now_ns - self.valve_changed_ns >= self.valve_travel_ns;
        if settled_open && near {
            self.sealed = true;
        }
        if !self.valve_commanded_open {
            self.sealed = false;
        }
        self.now_ns += PERIOD_NS;
        self.outputs.push(out.clone());
        out
    }

    fn target(&self, seq: u64, apple_id: u32, center_m: [f64; 3]) -> ArmTarget {
        ArmTarget {
            header: Header {
                msg_seq: seq,
                capture_ns: self.now_ns,
                publish_ns: 0,
            },
            arm_id: 1,
            apple_id,
            position_in_robot_m: center_m,
            radius_m: RADIUS_M,
            source_capture_ns: self.now_ns - 50_000_000,
            ..ArmTarget::default()
        }
    }

    fn run_until_idle(&mut self, max_s: f64) {
        let start = self.now_ns;
        loop {
            let out = self.tick();
            let busy = out.state.phase != PhaseCode::Idle;
            if (!busy && self.now_ns - start > 20 * PERIOD_NS)
                || (self.now_ns - start) as f64 * 1e-9 > max_s
            {
                break;
            }
        }
    }

    fn has(&self, f: impl Fn(&ArmNodeEvent) -> bool) -> bool {
        self.events.iter().any(|(_, e)| f(e))
    }
}

#[test]
fn picking_point_is_on_the_surface_facing_the_robot() {
    assert_eq!(
        picking_point_m([1.5, 0.1, 0.3], 0.04, 0.0),
        [1.5 - 0.04, 0.1, 0.3]
    );
    assert_eq!(
        picking_point_m([1.5, 0.1, 0.3], 0.04, 0.005),
        [1.5 - 0.045, 0.1, 0.3]
    );
    for bad in [0.0, -0.01, f64::NAN] {
        assert_eq!(
            picking_point_m([1.5, 0.0, 0.0], bad, 0.0),
            [1.5 - DEFAULT_APPLE_RADIUS_M, 0.0, 0.0]
        );
    }
}

#[test]
fn reachability_respects_the_workspace_and_the_resting_other_arm() {
    let config = ArmNodeConfig::default();
    // Straight ahead of arm 1 and of arm 2.
    assert!(pick_reachable(
        ArmId::Arm1,
        [1.40, 0.11, 0.30],
        RADIUS_M,
        &config
    ));
    assert!(pick_reachable(
        ArmId::Arm2,
        [1.40, -0.11, 0.30],
        RADIUS_M,
        &config
    ));
    // Beyond the prismatic stroke.
    assert!(!pick_reachable(
        ArmId::Arm1,
        [2.5, 0.11, 0.3],
        RADIUS_M,
        &config
    ));
    // Deep on arm 2's side: arm 1 would have to sweep past arm 2's resting tube.
    let far_right = [1.30, -0.20, 0.22];
    assert!(!pick_reachable(ArmId::Arm1, far_right, RADIUS_M, &config));
    assert!(pick_reachable(ArmId::Arm2, far_right, RADIUS_M, &config));
    let alone = ArmNodeConfig {
        other_arm_present: false,
        ..config
    };
    let ik_ok = inverse(
        &ArmParams::arm1(),
        picking_point_m(far_right, RADIUS_M, 0.0),
    )
    .is_ok();
    assert_eq!(
        pick_reachable(ArmId::Arm1, far_right, RADIUS_M, &alone),
        ik_ok
    );
}

#[test]
fn a_full_cycle_harvests_with_the_events_in_order_and_set_points_in_limits() {
    let mut b = Bench::single_arm();
    b.tick();
    b.target = Some(b.target(1, 7, APPLE_M));
    b.run_until_idle(20.0);
    let kinds: Vec<&ArmNodeEvent> = b
        .events
        .iter()
        .map(|(_, e)| e)
        .filter(|e| {
            matches!(
                e,
                ArmNodeEvent::TargetReceived { .. }
                    | ArmNodeEvent::TargetAccepted { .. }
                    | ArmNodeEvent::Cycle(_)
                    | ArmNodeEvent::AttemptEnded { .. }
                    | ArmNodeEvent::ValveRequested { .. }
            )
        })
        .collect();
    assert_eq!(
        kinds,
        vec![
            &ArmNodeEvent::TargetReceived { apple_id: 7 },
            &ArmNodeEvent::TargetAccepted { apple_id: 7 },
            &ArmNodeEvent::Cycle(CycleEvent::ApproachComplete),
            &ArmNodeEvent::ValveRequested {
                kind: ValveRequestKind::OpenForAttach,
                request_seq: 1
            },
            &ArmNodeEvent::Cycle(CycleEvent::Attached),
            &ArmNodeEvent::Cycle(CycleEvent::DetachComplete),
            &ArmNodeEvent::Cycle(CycleEvent::RetractComplete),
            &ArmNodeEvent::ValveRequested {
                kind: ValveRequestKind::Close,
                request_seq: 2
            },
            &ArmNodeEvent::Cycle(CycleEvent::CycleComplete { harvested: true }),
            &ArmNodeEvent::AttemptEnded {
                apple_id: 7,
                harvested: true,
                failure: None
            },
        ]
    );
    let phases: Vec<PhaseCode> = b
        .events
        .iter()
        .filter_map(|(_, e)| match e {
            ArmNodeEvent::PhaseChanged { to, .. } => Some(*to),
            _ => None,
        })
        .collect();
    assert_eq!(
        phases,
        vec![
            PhaseCode::Approach,
            PhaseCode::AttachDetach,
            PhaseCode::Retract,
            PhaseCode::Release,
            PhaseCode::Idle
        ]
    );
    assert_eq!(b.node.harvested_count(), 1);
    let limits = ArmParams::arm1().position_limits;
    for out in &b.outputs {
        if let ServoOrder::Track { position, velocity } = out.servo {
            assert!(limits.contains(&JointPosition::from_array(position)));
            assert!(velocity.iter().all(|v| v.is_finite()));
        }
        assert_eq!(out.state.arm_id, 1);
    }
    // The state names the apple while the cycle runs and reports the harvest after it.
    assert!(
        b.outputs
            .iter()
            .any(|o| o.state.phase == PhaseCode::Approach && o.state.apple_id == 7)
    );
    let last = b.outputs.last().expect("outputs");
    assert_eq!((last.state.apple_id, last.state.harvested_count), (0, 1));
    // The valve was requested open only at the apple and closed for the release.
    let open_ticks = b
        .outputs
        .iter()
        .filter(|o| o.valve_request.kind == ValveRequestKind::OpenForAttach);
    for o in open_ticks {
        assert!(
            o.state.phase == PhaseCode::AttachDetach || o.state.phase == PhaseCode::Retract,
            "{o:?}"
        );
    }
    // The same target sample is not offered again once done.
    for _ in 0..100 {
        b.tick();
    }
    assert_eq!(
        b.events
            .iter()
            .filter(|(_, e)| matches!(e, ArmNodeEvent::TargetAccepted { .. }))
            .count(),
        1
    );
}

#[test]
fn an_unreachable_target_is_dropped_with_its_reason() {
    let mut b = Bench::single_arm();
    b.target = Some(b.target(1, 3, [2.6, 0.1, 0.3]));
    for _ in 0..20 {
        b.tick();
    }
    let rejections: Vec<&ArmNodeEvent> = b
        .events
        .iter()
        .map(|(_, e)| e)
        .filter(|e| matches!(e, ArmNodeEvent::TargetRejected { .. }))
        .collect();
    assert_eq!(rejections.len(), 1);
    assert!(matches!(
        rejections[0],
        ArmNodeEvent::TargetRejected {
            apple_id: 3,
            reason: TargetRejection::Unreachable { .. },
            will_retry: false
        }
    ));
    // The published state says so, naming the apple.
    let state = b.outputs.last().map(|o| o.state).expect("ticked");
    assert_eq!(
        (state.target_status, state.target_apple_id),
        (TargetStatus::Refused.into(), 3)
    );
    // NaN and stale targets likewise.
    b.target = Some(b.target(2, 4, [f64::NAN, 0.0, 0.3]));
    b.tick();
    let mut stale = b.target(3, 5, APPLE_M);
    stale.source_capture_ns = b.now_ns - 3_000_000_000;
    b.target = Some(stale);
    b.tick();
    assert!(b.has(|e| matches!(
        e,
        ArmNodeEvent::TargetRejected {
            reason: TargetRejection::NonFinite { .. },
            will_retry: false,
            ..
        }
    )));
    assert!(b.has(|e| matches!(
        e,
        ArmNodeEvent::TargetRejected {
            reason: TargetRejection::Stale { .. },
            will_retry: false,
            ..
        }
    )));
    assert!(!b.has(|e| matches!(e, ArmNodeEvent::TargetAccepted { .. })));
    assert_eq!(
        b.outputs.last().map(|o| o.state.phase),
        Some(PhaseCode::Idle.into())
    );
}

#[test]
fn no_motion_starts_without_a_fresh_state_of_the_other_arm() {
    let mut b = Bench::new(ArmNodeConfig::default());
    b.target = Some(b.target(1, 9, APPLE_M));
    for _ in 0..10 {
        b.tick();
    }
    let deferred = b
        .events
        .iter()
        .filter(|(_, e)| matches!(e, ArmNodeEvent::TargetDeferred { apple_id: 9, .. }))
        .count();
    assert_eq!(deferred, 1);
    assert!(!b.has(|e| matches!(e, ArmNodeEvent::TargetAccepted { .. })));
    let status = |b: &Bench| {
        let state = b.outputs.last().map(|o| o.state).expect("ticked");
        (state.target_status.get().ok(), state.target_apple_id)
    };
    assert_eq!(status(&b), (Some(TargetStatus::Waiting), 9));
    // Withdrawn by the supervisor, then dispatched again.
    let mut withdrawal = b.target(2, 0, [f64::NAN; 3]);
    withdrawal.radius_m = f64::NAN;
    b.target = Some(withdrawal);
    b.tick();
    assert_eq!(status(&b), (Some(TargetStatus::None), 0));
    assert!(!b.has(|e| matches!(e, ArmNodeEvent::TargetRejected { .. })));
    b.target = Some(b.target(3, 9, APPLE_M));
    b.tick();
    assert_eq!(status(&b), (Some(TargetStatus::Waiting), 9));
    // Arm 2 idle at home, freshly reported: the target is taken.
    let params = ArmParams::arm2();
    b.other = Some(ArmState {
        header: Header {
            msg_seq: 1,
            capture_ns: b.now_ns,
            publish_ns: 0,
        },
        arm_id: 2,
        phase: PhaseCode::Idle.into(),
        end_effector_in_robot_m: forward(&params.links, &params.home),
        ..ArmState::default()
    });
    b.tick();
    assert!(b.has(|e| matches!(e, ArmNodeEvent::TargetAccepted { apple_id: 9 })));
    assert_eq!(status(&b), (Some(TargetStatus::None), 0));
}

#[test]
fn emergency_stop_brakes_closes_and_abandons_the_attempt() {
    let mut b = Bench::single_arm();
    b.target = Some(b.target(1, 2, APPLE_M));
    for _ in 0..100 {
        b.tick();
    }
    assert_eq!(
        b.outputs.last().map(|o| o.state.phase),
        Some(PhaseCode::Approach.into())
    );
    b.emergency_stop = true;
    let out = b.tick();
    assert_eq!(out.servo, ServoOrder::Hold);
    assert_eq!(out.valve_request.kind, ValveRequestKind::Close);
    assert_eq!(out.state.phase, PhaseCode::Stopped);
    assert!(
        out.events
            .contains(&ArmNodeEvent::EmergencyStop { engaged: true })
    );
    assert!(out.events.contains(&ArmNodeEvent::AttemptEnded {
        apple_id: 2,
        harvested: false,
        failure: Some(AttemptFailure::EmergencyStop)
    }));
    // While engaged nothing is taken.
    b.target = Some(b.target(2, 3, APPLE_M));
    for _ in 0..50 {
        let out = b.tick();
        assert_eq!(out.servo, ServoOrder::Hold);
    }
    assert!(b.v.iter().all(|v| v.abs() < 1e-6));
    b.emergency_stop = false;
    let out = b.tick();
    assert!(
        out.events
            .contains(&ArmNodeEvent::EmergencyStop { engaged: false })
    );
    assert_eq!(out.state.phase, PhaseCode::Idle);
    // A new target after the release starts from where the arm stopped.
    b.target = Some(b.target(3, 4, APPLE_M));
    b.tick();
    assert!(b.has(|e| matches!(e, ArmNodeEvent::TargetAccepted { apple_id: 4 })));
}

#[test]
fn the_cycle_sees_the_valve_open_only_at_the_end_stop_and_closed_only_once_vented() {
    let node = ArmNode::new(ArmId::Arm1, ArmNodeConfig::default()).expect("node");
    let state = |open: bool, transit: bool, pressure: f32, sealed: bool| VacuumState {
        valve_open: [u8::from(open), u8::from(!open), 0, 1],
        valve_in_transit: [u8::from(transit), u8::from(transit), 0, 0],
        pressure_mmh2o: [pressure, 0.0, 2400.0],
        arm_attachment: [attachment(sealed, open), ArmAttachment::Closed.into()],
        ..VacuumState::default()
    };
    assert_eq!(node.vacuum_view(None), (false, false));
    // Opening: closed until the gate arrives.
    assert_eq!(
        node.vacuum_view(Some(&state(true, true, 300.0, false))),
        (false, false)
    );
    assert_eq!(
        node.vacuum_view(Some(&state(true, false, 700.0, false))),
        (true, false)
    );
    assert_eq!(
        node.vacuum_view(Some(&state(true, false, 2300.0, true))),
        (true, true)
    );
    // Closing: open until the gate arrived and the tube vented.
    assert_eq!(
        node.vacuum_view(Some(&state(false, true, 2000.0, false))),
        (true, false)
    );
    assert_eq!(
        node.vacuum_view(Some(&state(false, false, 600.0, false))),
        (true, false)
    );
    assert_eq!(
        node.vacuum_view(Some(&state(false, false, 20.0, false))),
        (false, false)
    );
}

#[test]
fn a_missed_deadline_brakes_the_arm_and_the_pick_goes_on() {
    let mut b = Bench::single_arm();
    b.tick();
    b.target = Some(b.target(1, 7, APPLE_M));
    for _ in 0..60 {
        b.tick();
    }
    assert!(matches!(b.tick().servo, ServoOrder::Track { .. }));
    // The loop is held up for 5 periods: the next step brakes the drives.
    b.now_ns += 4 * PERIOD_NS;
    let out = b.tick();
    assert_eq!(out.servo, ServoOrder::Hold);
    assert!(
        out.events
            .iter()
            .any(|e| matches!(e, ArmNodeEvent::Cycle(CycleEvent::DeadlineMissed { .. }))),
        "{:?}",
        out.events
    );
    assert_eq!(out.state.phase, PhaseCode::Approach);
    // On time again, the arm tracks and the attempt ends with the apple.
    assert!(matches!(b.tick().servo, ServoOrder::Track { .. }));
    b.run_until_idle(20.0);
    assert!(b.has(|e| matches!(
        e,
        ArmNodeEvent::AttemptEnded {
            apple_id: 7,
            harvested: true,
            ..
        }
    )));
}

#[test]
fn a_refusal_is_reported_once_per_request_and_reason() {
    let mut b = Bench::single_arm();
    b.vacuum_follows_requests = false;
    b.target = Some(b.target(1, 5, APPLE_M));
    let mut refused_once = false;
    for _ in 0..1200 {
        let out = b.tick();
        if out.valve_request.kind == ValveRequestKind::OpenForAttach && !refused_once {
            refused_once = true;
            b.grant = Some(ValveGrant {
                arm_id: 1,
                granted: 0,
                reason: 5,
                request_seq: out.valve_request.request_seq,
                ..ValveGrant::default()
            });
        }
    }
    let refusals = b
        .events
        .iter()
        .filter(|(_, e)| matches!(e, ArmNodeEvent::ValveRefused { reason_code: 5 }))
        .count();
    assert_eq!(refusals, 1);
}

#[test]
fn the_set_point_integrates_the_rates_and_resynchronises_when_the_arm_lags() {
    let mut node = ArmNode::new(ArmId::Arm1, ArmNodeConfig::default()).expect("node");
    let q = JointPosition::from_array([0.1, 0.0, 0.0, 0.0]);
    let rate = JointVelocity::from_array([0.2, 0.0, 0.0, 0.0]);
    assert_eq!(
        node.track(&q, &rate, 0.005),
        ServoOrder::Track {
            position: [0.1, 0.0, 0.0, 0.0],
            velocity: [0.2, 0.0, 0.0, 0.0]
        }
    );
    // The arm has not moved (2 mm behind): the set-point runs ahead by the integrated rate.
    let ServoOrder::Track { position, .. } = node.track(&q, &rate, 0.01) else {
        panic!("tracking");
    };
    assert!((position[0] - 0.102).abs() < 1e-12);
    // 4 mm, 6 mm, ... behind; past 1 cm it resynchronises to the encoder.
    let mut last = 0.0;
    for _ in 0..10 {
        let ServoOrder::Track { position, .. } = node.track(&q, &rate, 0.01) else {
            panic!("tracking");
        };
        last = position[0];
    }
    assert!(last - 0.1 <= 0.01 + 1e-12, "{last}");
    // The set-point never leaves the limits.
    let fast = JointVelocity::from_array([50.0, 0.0, 0.0, 0.0]);
    let at_limit = JointPosition::from_array([0.6, 0.0, 0.0, 0.0]);
    let ServoOrder::Track { position, .. } = node.track(&at_limit, &fast, 0.01) else {
        panic!("tracking");
    };
    assert!(position[0] <= 0.6);
}

#[test]
fn config_is_checked() {
    let bad = ArmNodeConfig {
        setpoint_resync_m: 0.0,
        ..ArmNodeConfig::default()
    };
    assert!(matches!(
        ArmNode::new(ArmId::Arm1, bad),
        Err(ArmNodeError::Invalid {
            field: "setpoint_resync_m",
            ..
        })
    ));
    let bad = ArmNodeConfig {
        cycle: CycleConfig {
            speed_fraction: 2.0,
            ..CycleConfig::default()
        },
        ..ArmNodeConfig::default()
    };
    assert!(matches!(
        ArmNode::new(ArmId::Arm2, bad),
        Err(ArmNodeError::Cycle(_))
    ));
}

// --- Operator: held targets and manual moves.

#[test]
fn a_held_target_waits_and_starts_once_released() {
    let mut bench = Bench::single_arm();
    bench.node.hold_targets(true);
    bench.target = Some(bench.target(1, 42, APPLE_M));
    for _ in 0..20 {
        let out = bench.tick();
        assert_eq!(out.state.phase, PhaseCode::Idle);
        assert_eq!(out.state.target_status, TargetStatus::Waiting);
        assert_eq!(out.state.target_apple_id, 42);
    }
    assert!(!bench.has(|e| matches!(e, ArmNodeEvent::TargetAccepted { .. })));
    bench.node.hold_targets(false);
    bench.tick();
    assert!(bench.has(|e| matches!(e, ArmNodeEvent::TargetAccepted { apple_id: 42 })));
}

#[test]
fn a_manual_move_reaches_its_goal_and_the_emergency_stop_ends_it() {
    let mut bench = Bench::single_arm();
    bench.tick();
    let mut goal = bench.q;
    goal[1] += 0.1;
    let duration_s = bench
        .node
        .start_manual(bench.now_ns, goal, 0.5, 9)
        .expect("manual move");
    assert!(bench.node.manual_active());
    let ticks = (duration_s * 1e9 / PERIOD_NS as f64) as usize + 100;
    for _ in 0..ticks {
        let out = bench.tick();
        assert_eq!(out.state.phase, PhaseCode::Idle);
        if let ServoOrder::Track { position, .. } = out.servo {
            assert!(position[1] <= goal[1] + 1e-9);
        }
    }
    assert!(!bench.node.manual_active());
    assert!((bench.q[1] - goal[1]).abs() < 0.005, "{:?}", bench.q);

    // Outside the limits: refused, nothing moves.
    let mut far = bench.q;
    far[0] = 5.0;
    assert!(matches!(
        bench.node.start_manual(bench.now_ns, far, 0.5, 10),
        Err(ManualRefusal::Plan(_))
    ));
    assert!(!bench.node.manual_active());

    // The emergency stop ends a move under way and refuses new ones while engaged.
    goal[1] -= 0.1;
    bench
        .node
        .start_manual(bench.now_ns, goal, 0.5, 11)
        .expect("manual move");
    bench.tick();
    bench.emergency_stop = true;
    let out = bench.tick();
    assert_eq!(out.servo, ServoOrder::Hold);
    assert!(!bench.node.manual_active());
    assert_eq!(
        bench.node.start_manual(bench.now_ns, goal, 0.5, 12),
        Err(ManualRefusal::EmergencyStop)
    );
}
