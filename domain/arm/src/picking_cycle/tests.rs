use super::motion::distance_m;
use super::*;
use crate::servo_model::FirstOrderServo;
use harvest_robot_model::joint::JointVelocity;
use harvest_robot_model::kinematics::IkError;

const PERIOD_NS: u64 = 5_000_000; // 200 Hz
const SUBSTEPS: u64 = 5;
/// Suction cup capture radius used by the simulated world (section 2.2: +-1.5 cm).
const CAPTURE_RADIUS_M: f64 = 0.015;

/// One arm with simulated servos, valve and apple.
struct World {
    cycle: PickingCycle,
    servo: FirstOrderServo,
    now_ns: u64,
    valve_open: bool,
    valve_obeys: bool,
    attached: bool,
    apple_m: [f64; 3],
    sealable: bool,
    drop_apple_in_retract: bool,
    feedback_delay_ns: u64,
    phase_log: Vec<(CyclePhase, f64)>,
    events: Vec<(CycleEvent, f64)>,
    outputs: Vec<CycleOutput>,
    max_tracking_error_m: f64,
    /// Largest twist magnitude the servo reached, rad.
    peak_twist_rad: f64,
}

impl World {
    fn new(params: ArmParams, other: ArmParams, apple_m: [f64; 3]) -> Self {
        Self::with_config(params, other, apple_m, CycleConfig::default())
    }

    fn with_config(
        params: ArmParams,
        other: ArmParams,
        apple_m: [f64; 3],
        config: CycleConfig,
    ) -> Self {
        let cycle = PickingCycle::new(params, other, config).unwrap();
        Self {
            cycle,
            servo: FirstOrderServo::new(params.position_limits, 0.02, params.home),
            now_ns: 10_000_000_000,
            valve_open: false,
            valve_obeys: true,
            attached: false,
            apple_m,
            sealable: true,
            drop_apple_in_retract: false,
            feedback_delay_ns: 0,
            phase_log: vec![(CyclePhase::Idle, 0.0)],
            events: Vec::new(),
            outputs: Vec::new(),
            max_tracking_error_m: 0.0,
            peak_twist_rad: 0.0,
        }
    }

    fn t_s(&self) -> f64 {
        (self.now_ns - 10_000_000_000) as f64 * 1e-9
    }

    fn input(&self, target: Option<TargetRequest>, other: Option<OtherArmState>) -> CycleInput {
        CycleInput {
            now_ns: self.now_ns,
            joints: self.servo.position,
            joints_stamp_ns: self.now_ns - self.feedback_delay_ns,
            valve_open: self.valve_open,
            apple_attached: self.attached,
            target,
            other_arm: other,
        }
    }

    fn tick(&mut self, target: Option<TargetRequest>, other: Option<OtherArmState>) -> CycleOutput {
        let out = self.cycle.step(&self.input(target, other));
        let t = self.t_s();
        if let Some(r) = &out.reference
            && matches!(out.phase, CyclePhase::Approach | CyclePhase::Retract)
        {
            let e = distance_m(r.position_m, out.end_effector_m);
            self.max_tracking_error_m = self.max_tracking_error_m.max(e);
        }
        if self.phase_log.last().map(|p| p.0) != Some(out.phase) {
            self.phase_log.push((out.phase, t));
        }
        if let Some(e) = out.event {
            self.events.push((e, t));
        }
        if self.valve_obeys {
            self.valve_open = out.valve_request == ValveRequest::Open;
        }
        let ee = forward(&self.cycle.params.links, &self.servo.position);
        if self.valve_open
            && self.sealable
            && !self.attached
            && distance_m(ee, self.apple_m) <= CAPTURE_RADIUS_M
        {
            self.attached = true;
        }
        if !self.valve_open
            || (self.drop_apple_in_retract && out.phase == CyclePhase::Retract && t > 0.0)
        {
            self.attached = false;
        }
        for _ in 0..SUBSTEPS {
            self.servo
                .step(&out.command.velocity, &JointVelocity::ZERO, 1e-3);
        }
        self.peak_twist_rad = self.peak_twist_rad.max(self.servo.position.twist_rad.abs());
        self.now_ns += PERIOD_NS;
        self.outputs.push(out.clone());
        out
    }

    fn target(&self, id: u64) -> TargetRequest {
        TargetRequest {
            id,
            position_m: self.apple_m,
            detected_at_ns: self.now_ns - 100_000_000,
        }
    }

    /// Offers the apple once, then runs until Idle again (or `max_s`).
    fn run_cycle(&mut self, max_s: f64) -> TargetDecision {
        let target = self.target(1);
        let out = self.tick(Some(target), None);
        let decision = out.target_decision.clone().unwrap();
        let start = self.t_s();
        while self.cycle.phase() != CyclePhase::Idle && self.t_s() - start < max_s {
            self.tick(None, None);
        }
        decision
    }

    fn phase_durations(&self) -> Vec<(CyclePhase, f64)> {
        self.phase_log
            .windows(2)
            .map(|w| (w[0].0, w[1].1 - w[0].1))
            .skip(1)
            .collect()
    }

    fn event_kinds(&self) -> Vec<CycleEvent> {
        self.events.iter().map(|e| e.0).collect()
    }
}

/// A mid-workspace apple of arm 1, 0.52 m from the home end-effector position.
const TYPICAL_APPLE_M: [f64; 3] = [1.45, -0.05, 0.50];

#[test]
fn cycle_timing_matches_the_fig_12_analysis() {
    // Fig. 12's attach phase is short: an eighth of a turn of twist here. The default quarter
    // turn (more stem relief, see `CycleConfig::detach_twist_rad`) adds about 0.2 s; the next
    // test measures it.
    let config = CycleConfig {
        detach_twist_rad: std::f64::consts::FRAC_PI_4,
        ..CycleConfig::default()
    };
    let mut w = World::with_config(
        ArmParams::arm1(),
        ArmParams::arm2(),
        TYPICAL_APPLE_M,
        config,
    );
    let decision = w.run_cycle(20.0);
    assert_eq!(decision, TargetDecision::Accepted { id: 1 });
    assert_eq!(
        w.event_kinds(),
        vec![
            CycleEvent::ApproachComplete,
            CycleEvent::Attached,
            CycleEvent::DetachComplete,
            CycleEvent::RetractComplete,
            CycleEvent::CycleComplete { harvested: true },
        ]
    );
    let durations = w.phase_durations();
    let phases: Vec<CyclePhase> = durations.iter().map(|d| d.0).collect();
    assert_eq!(
        phases,
        vec![
            CyclePhase::Approach,
            CyclePhase::Attach,
            CyclePhase::Retract,
            CyclePhase::Release
        ]
    );
    let d: Vec<f64> = durations.iter().map(|d| d.1).collect();
    let total: f64 = d.iter().sum();
    println!(
        "approach {:.3} s, attach {:.3} s, retract {:.3} s, release {:.3} s, total {total:.3} s, \
         max tracking error {:.1} mm",
        d[0],
        d[1],
        d[2],
        d[3],
        w.max_tracking_error_m * 1e3
    );
    // Fig. 12 (derived in CONTROLLER.md): arm movement ~2.0 s each way, attach + release
    // ~0.5 s, one cycle ~4.5 s.
    assert!((1.6..=2.4).contains(&d[0]), "approach {}", d[0]);
    assert!((1.6..=2.4).contains(&d[2]), "retract {}", d[2]);
    assert!((d[0] - d[2]).abs() < 0.3, "approach and retract differ");
    assert!(
        (0.3..=0.8).contains(&(d[1] + d[3])),
        "attach + release {}",
        d[1] + d[3]
    );
    assert!((4.0..=5.0).contains(&total), "cycle {total}");
    // The valve was open exactly from the end of the approach to the drop-off.
    let open: Vec<&CycleOutput> = w
        .outputs
        .iter()
        .filter(|o| o.valve_request == ValveRequest::Open)
        .collect();
    assert!(
        open.iter()
            .all(|o| matches!(o.phase, CyclePhase::Attach | CyclePhase::Retract))
    );
    assert!(w.outputs.iter().all(|o| !o.command.stopped));
    // Back home at the end.
    let home = forward(&ArmParams::arm1().links, &ArmParams::arm1().home);
    let ee = forward(&ArmParams::arm1().links, &w.servo.position);
    assert!(distance_m(home, ee) < 0.005);
}

/// Attach duration and the largest twist reached, with `config`.
fn attach_and_peak_twist(config: CycleConfig) -> (f64, f64) {
    let mut w = World::with_config(
        ArmParams::arm1(),
        ArmParams::arm2(),
        TYPICAL_APPLE_M,
        config,
    );
    assert_eq!(w.run_cycle(20.0), TargetDecision::Accepted { id: 1 });
    let attach_s = w
        .phase_durations()
        .iter()
        .find(|d| d.0 == CyclePhase::Attach)
        .map(|d| d.1)
        .unwrap();
    (attach_s, w.peak_twist_rad)
}

#[test]
fn the_default_detach_twist_is_a_quarter_turn() {
    let quarter = CycleConfig::default();
    let eighth = CycleConfig {
        detach_twist_rad: std::f64::consts::FRAC_PI_4,
        ..quarter
    };
    let (quarter_attach_s, quarter_peak_rad) = attach_and_peak_twist(quarter);
    let (eighth_attach_s, eighth_peak_rad) = attach_and_peak_twist(eighth);
    println!(
        "attach: quarter turn {quarter_attach_s:.3} s (peak {quarter_peak_rad:.3} rad), \
         eighth {eighth_attach_s:.3} s (peak {eighth_peak_rad:.3} rad)"
    );
    let tolerance = CycleConfig::default().twist_tolerance_rad;
    assert!((quarter_peak_rad - std::f64::consts::FRAC_PI_2).abs() <= tolerance + 0.02);
    assert!((eighth_peak_rad - std::f64::consts::FRAC_PI_4).abs() <= tolerance + 0.02);
    // Simulated time: the extra eighth of a turn at the twist joint's speed limit (0.6 of
    // 1 rev/s) takes at least 0.2 s.
    assert!(quarter_attach_s - eighth_attach_s >= 0.2);
}

#[test]
fn failed_attachment_closes_the_valve_and_skips_release() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    w.sealable = false;
    w.run_cycle(20.0);
    assert_eq!(
        w.event_kinds(),
        vec![
            CycleEvent::ApproachComplete,
            CycleEvent::AttachFailed,
            CycleEvent::CycleComplete { harvested: false },
        ]
    );
    assert!(w.phase_log.iter().all(|p| p.0 != CyclePhase::Release));
    let failed = w
        .outputs
        .iter()
        .find(|o| o.event == Some(CycleEvent::AttachFailed))
        .unwrap();
    assert_eq!(failed.valve_request, ValveRequest::Closed);
    assert_eq!(failed.phase, CyclePhase::Retract);
}

#[test]
fn apple_lost_during_retract_closes_the_valve_at_once() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    w.drop_apple_in_retract = true;
    w.run_cycle(20.0);
    let kinds = w.event_kinds();
    assert_eq!(
        kinds,
        vec![
            CycleEvent::ApproachComplete,
            CycleEvent::Attached,
            CycleEvent::DetachComplete,
            CycleEvent::AppleLost,
            CycleEvent::CycleComplete { harvested: false },
        ]
    );
    let lost = w
        .outputs
        .iter()
        .position(|o| o.event == Some(CycleEvent::AppleLost))
        .unwrap();
    assert_eq!(w.outputs[lost].valve_request, ValveRequest::Closed);
    assert!(
        w.outputs[lost..]
            .iter()
            .all(|o| o.valve_request == ValveRequest::Closed)
    );
    assert!(w.phase_log.iter().all(|p| p.0 != CyclePhase::Release));
}

#[test]
fn valve_never_granted_times_out_and_retracts() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    w.valve_obeys = false;
    w.run_cycle(20.0);
    assert_eq!(
        w.event_kinds(),
        vec![
            CycleEvent::ApproachComplete,
            CycleEvent::ValveGrantTimeout,
            CycleEvent::CycleComplete { harvested: false },
        ]
    );
    let (_, t_complete) = w.events[0];
    let (_, t_timeout) = w.events[1];
    assert!(t_timeout - t_complete >= CycleConfig::default().valve_grant_timeout_s);
}

#[test]
fn bad_targets_are_rejected_with_a_reason() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    w.tick(None, None);
    let now = w.now_ns;
    let reject = |w: &mut World, t: TargetRequest| match w.tick(Some(t), None).target_decision {
        Some(TargetDecision::Rejected(r)) => r,
        other => panic!("expected a rejection, got {other:?}"),
    };
    let base = TargetRequest {
        id: 7,
        position_m: TYPICAL_APPLE_M,
        detected_at_ns: now,
    };
    let r = reject(
        &mut w,
        TargetRequest {
            position_m: [f64::NAN, 0.0, 0.4],
            ..base
        },
    );
    assert!(matches!(r, TargetRejection::NonFinite { id: 7, .. }) && !r.is_retryable());
    let t = TargetRequest {
        detected_at_ns: w.now_ns - 3_000_000_000,
        ..base
    };
    let r = reject(&mut w, t);
    assert!(matches!(r, TargetRejection::Stale { .. }) && !r.is_retryable());
    let t = TargetRequest {
        detected_at_ns: w.now_ns + 1_000_000,
        ..base
    };
    let r = reject(&mut w, t);
    assert!(matches!(r, TargetRejection::FromFuture { .. }));
    let t = TargetRequest {
        position_m: [2.5, 0.11, 0.221],
        detected_at_ns: w.now_ns,
        ..base
    };
    let r = reject(&mut w, t);
    assert!(matches!(
        r,
        TargetRejection::Unreachable {
            reason: IkError::JointLimit { .. },
            ..
        }
    ));
    assert_eq!(w.cycle.phase(), CyclePhase::Idle);
    // Accept, then a different target while busy is refused (retryable); a repeat of the
    // current one is silently ignored.
    let ok = w.tick(
        Some(TargetRequest {
            detected_at_ns: w.now_ns,
            ..base
        }),
        None,
    );
    assert_eq!(ok.target_decision, Some(TargetDecision::Accepted { id: 7 }));
    assert_eq!(ok.goal_m, Some(TYPICAL_APPLE_M));
    let r = reject(&mut w, TargetRequest { id: 8, ..base });
    assert!(matches!(
        r,
        TargetRejection::Busy {
            id: 8,
            phase: CyclePhase::Approach
        }
    ));
    assert!(r.is_retryable());
    assert_eq!(w.tick(Some(base), None).target_decision, None);
}

#[test]
fn clearance_against_the_other_arm() {
    let a1 = ArmParams::arm1();
    let a2 = ArmParams::arm2();
    let mut w = World::new(a1, a2, TYPICAL_APPLE_M);
    let other_home = forward(&a2.links, &a2.home);
    // Arm 2 idle at home: far enough.
    let idle = OtherArmState {
        phase: CyclePhase::Idle,
        end_effector_m: other_home,
        goal_m: None,
    };
    // Arm 2 heading across to the +y side, through arm 1's path.
    let crossing = OtherArmState {
        phase: CyclePhase::Approach,
        end_effector_m: other_home,
        goal_m: Some([1.40, 0.05, 0.45]),
    };
    let target = TargetRequest {
        id: 3,
        position_m: TYPICAL_APPLE_M,
        detected_at_ns: w.now_ns,
    };
    let out = w.tick(Some(target), Some(crossing));
    match out.target_decision {
        Some(TargetDecision::Rejected(r)) => {
            assert!(
                matches!(r, TargetRejection::ClearanceConflict { .. }),
                "{r}"
            );
            assert!(r.is_retryable());
        }
        other => panic!("expected a clearance conflict, got {other:?}"),
    }
    let unknown = OtherArmState {
        goal_m: None,
        ..crossing
    };
    let target = TargetRequest {
        detected_at_ns: w.now_ns,
        ..target
    };
    assert!(matches!(
        w.tick(Some(target), Some(unknown)).target_decision,
        Some(TargetDecision::Rejected(
            TargetRejection::OtherArmGoalUnknown { id: 3 }
        ))
    ));
    let target = TargetRequest {
        detected_at_ns: w.now_ns,
        ..target
    };
    assert_eq!(
        w.tick(Some(target), Some(idle)).target_decision,
        Some(TargetDecision::Accepted { id: 3 })
    );
}

#[test]
fn stale_feedback_stops_the_arm_and_the_motion_resumes_afterwards() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    let target = w.target(1);
    w.tick(Some(target), None);
    for _ in 0..100 {
        w.tick(None, None);
    }
    w.feedback_delay_ns = 200_000_000;
    let out = w.tick(None, None);
    assert!(out.command.stopped);
    assert_eq!(out.command.velocity, JointVelocity::ZERO);
    assert!(matches!(
        out.event,
        Some(CycleEvent::FeedbackInvalid { .. })
    ));
    assert_eq!(out.phase, CyclePhase::Approach);
    for _ in 0..20 {
        w.tick(None, None);
    }
    w.feedback_delay_ns = 0;
    let start = w.t_s();
    while w.cycle.phase() != CyclePhase::Idle && w.t_s() - start < 20.0 {
        w.tick(None, None);
    }
    assert_eq!(
        w.events.last().map(|e| e.0),
        Some(CycleEvent::CycleComplete { harvested: true })
    );
}

#[test]
fn a_late_step_stops_the_arm_and_the_motion_resumes_afterwards() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    let target = w.target(1);
    w.tick(Some(target), None);
    for _ in 0..100 {
        w.tick(None, None);
    }
    // Three periods between steps is within the bound (default 3 periods).
    w.now_ns += 2 * PERIOD_NS;
    let out = w.tick(None, None);
    assert!(!out.command.stopped, "{out:?}");
    assert_eq!(out.event, None);
    // Four periods: the loop missed its deadline; the arm is held where it is.
    w.now_ns += 3 * PERIOD_NS;
    let out = w.tick(None, None);
    assert!(out.command.stopped);
    assert_eq!(out.command.velocity, JointVelocity::ZERO);
    match out.event {
        Some(CycleEvent::DeadlineMissed { gap_s }) => {
            assert!((gap_s - 0.020).abs() < 1e-9, "{gap_s}")
        }
        other => panic!("expected a deadline miss, got {other:?}"),
    }
    assert_eq!(out.phase, CyclePhase::Approach);
    // On time again: the approach restarts from where the arm is and the cycle completes.
    let out = w.tick(None, None);
    assert!(!out.command.stopped);
    let start = w.t_s();
    while w.cycle.phase() != CyclePhase::Idle && w.t_s() - start < 20.0 {
        w.tick(None, None);
    }
    assert_eq!(
        w.events.last().map(|e| e.0),
        Some(CycleEvent::CycleComplete { harvested: true })
    );
}

#[test]
fn a_late_step_leaves_an_offered_target_for_the_next_step() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    w.tick(None, None);
    w.now_ns += 10 * PERIOD_NS;
    let target = w.target(4);
    let out = w.tick(Some(target), None);
    assert_eq!(out.target_decision, None);
    assert_eq!(out.phase, CyclePhase::Idle);
    let target = w.target(4);
    assert_eq!(
        w.tick(Some(target), None).target_decision,
        Some(TargetDecision::Accepted { id: 4 })
    );
}

#[test]
fn no_motion_starts_without_fresh_feedback() {
    let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
    w.feedback_delay_ns = 1_000_000_000;
    let target = w.target(9);
    let out = w.tick(Some(target), None);
    assert_eq!(
        out.target_decision,
        Some(TargetDecision::Rejected(TargetRejection::NoFeedback {
            id: 9
        }))
    );
    assert_eq!(out.phase, CyclePhase::Idle);
    assert!(out.command.stopped);
    w.feedback_delay_ns = 0;
    let target = w.target(9);
    assert_eq!(
        w.tick(Some(target), None).target_decision,
        Some(TargetDecision::Accepted { id: 9 })
    );
}

#[test]
fn other_arm_state_mirrors_the_output() {
    let mut w = World::new(ArmParams::arm2(), ArmParams::arm1(), [1.35, -0.15, 0.35]);
    let target = w.target(5);
    let out = w.tick(Some(target), None);
    let other = OtherArmState::from_output(&out);
    assert_eq!(other.phase, CyclePhase::Approach);
    assert_eq!(other.goal_m, Some([1.35, -0.15, 0.35]));
    assert_eq!(other.end_effector_m, out.end_effector_m);
}

/// Both arms with a shared vacuum: the test plays the coordinator of eq. 11 (a valve opens
/// only while the other arm is not attempting an attachment) and keeps offering each arm an
/// apple whenever it is idle. With independent cycles and staggered attachments, two apples
/// are released per single-arm cycle: the 2024 timeline of Fig. 12.
#[test]
fn two_arms_interleave_as_in_the_2024_timeline() {
    let (a1, a2) = (ArmParams::arm1(), ArmParams::arm2());
    let mut w1 = World::new(a1, a2, [1.45, 0.10, 0.50]);
    let mut w2 = World::new(a2, a1, [1.45, -0.12, 0.50]);
    w1.valve_obeys = false;
    w2.valve_obeys = false;
    let mut last2: Option<CycleOutput> = None;
    let mut next_id = 100;
    let mut releases = Vec::new();
    let mut clearance_refusals = 0;
    for _ in 0..(40.0 / 0.005) as usize {
        let offer1 = (w1.cycle.phase() == CyclePhase::Idle).then(|| w1.target(next_id));
        let other1 = last2.as_ref().map(OtherArmState::from_output);
        let out1 = w1.tick(offer1, other1);
        let offer2 = (w2.cycle.phase() == CyclePhase::Idle).then(|| w2.target(next_id + 1));
        let out2 = w2.tick(offer2, Some(OtherArmState::from_output(&out1)));
        for out in [&out1, &out2] {
            match &out.target_decision {
                Some(TargetDecision::Accepted { .. }) => next_id += 2,
                Some(TargetDecision::Rejected(TargetRejection::ClearanceConflict { .. })) => {
                    clearance_refusals += 1
                }
                Some(TargetDecision::Rejected(r)) => panic!("unexpected rejection {r}"),
                None => {}
            }
            if out.event == Some(CycleEvent::CycleComplete { harvested: true }) {
                releases.push(w1.t_s());
            }
        }
        // Coordinator (eq. 11): a closed valve opens only while the other arm is not
        // attempting an attachment (open and nothing attached); an open valve stays open
        // while requested (a held apple seals its tube). Arm 1 wins ties.
        let attempting2 = w2.valve_open && !w2.attached;
        let open1 = out1.valve_request == ValveRequest::Open && (w1.valve_open || !attempting2);
        let attempting1 = open1 && !w1.attached;
        let open2 = out2.valve_request == ValveRequest::Open && (w2.valve_open || !attempting1);
        let both_attempting = open1 && open2 && !w1.attached && !w2.attached;
        assert!(!both_attempting, "both arms attempting an attachment");
        w1.valve_open = open1;
        w2.valve_open = open2;
        last2 = Some(out2);
    }
    assert!(
        releases.len() >= 14,
        "only {} apples in 40 s",
        releases.len()
    );
    let steady = &releases[2..];
    let per_apple_s = (steady[steady.len() - 1] - steady[0]) / (steady.len() - 1) as f64;
    println!(
        "two arms: {} apples in 40 s, {per_apple_s:.2} s per apple, {clearance_refusals} \
         clearance refusals",
        releases.len()
    );
    // Fig. 12, 2024 version: half the single-arm cycle (4.5 s -> 2.25 s per apple).
    assert!(
        (1.9..=2.6).contains(&per_apple_s),
        "{per_apple_s} s per apple"
    );
}

#[test]
fn config_validates_and_round_trips() {
    assert_eq!(CycleConfig::default().validate(), Ok(()));
    let bad = CycleConfig {
        speed_fraction: 0.0,
        ..CycleConfig::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(CycleConfigError::Invalid {
            field: "speed_fraction",
            ..
        })
    ));
    let bad = CycleConfig {
        release_dwell_s: f64::NAN,
        ..CycleConfig::default()
    };
    assert!(PickingCycle::new(ArmParams::arm1(), ArmParams::arm2(), bad).is_err());
    let text = toml::to_string(&CycleConfig::default()).unwrap();
    let back: CycleConfig = toml::from_str(&text).unwrap();
    assert_eq!(back, CycleConfig::default());
    assert!(toml::from_str::<CycleConfig>(&format!("{text}\nbogus = 1\n")).is_err());
    // Settings written before `max_tick_gap_periods` existed still read, with its default.
    let older: String = text
        .lines()
        .filter(|line| !line.starts_with("max_tick_gap_periods"))
        .map(|line| format!("{line}\n"))
        .collect();
    let back: CycleConfig = toml::from_str(&older).unwrap();
    assert_eq!(back.max_tick_gap_periods, 3.0);
    let bad = CycleConfig {
        max_tick_gap_periods: 1.0,
        ..CycleConfig::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(CycleConfigError::Invalid {
            field: "max_tick_gap_periods",
            ..
        })
    ));
}
