//! Behaviour every [`ArmServos`] implementation must show, written once and generic over the
//! trait (harness: [`crate::conformance`]):
//!
//! - encoder feedback arrives, within the joint limits, with stamps that never go back and do
//!   advance;
//! - a set-point streamed at the control rate is reached within tolerance, approached the way a
//!   first-order (well-damped) servo does: never moving away from it, overshooting by at most
//!   a small fraction of the step;
//! - set-points outside the limits or not finite are refused with kind `InvalidRequest` and do
//!   not move the arm;
//! - `hold` brakes a moving arm short of its target and keeps it there.
//!
//! Set-points are re-sent every poll (the servo contract expects >= 200 Hz streaming; a drive
//! that stops receiving them holds). The drivers may share one arm: targets are chosen from
//! where the arm stands, inside the limits.

use super::{ArmServos, JOINT_COUNT, JointFeedback};
use crate::conformance::{
    Check, ConformanceError, ConformanceReport, PollBounds, Probe, call, expect_refusal,
    poll_until, run_checks, stamps_advance, violated,
};
use crate::error_kind::ErrorKind;
use std::time::Duration;

const JOINT_NAMES: [&str; JOINT_COUNT] = ["D", "theta", "phi", "twist"];

/// The arm's declared limits and the suite's sizes and bounds. Units per joint:
/// `[D m, theta rad, phi rad, twist rad]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoConformanceConfig {
    /// `[min, max]` position per joint, as the driver declares them ([dual-arm Table 1] for the
    /// real arms).
    pub limits: [[f64; 2]; JOINT_COUNT],
    /// Size of the test step per joint.
    pub step: [f64; JOINT_COUNT],
    /// Largest distance from the set-point that counts as reached (and the slack of every
    /// position comparison).
    pub tolerance: [f64; JOINT_COUNT],
    /// Largest overshoot allowed, as a fraction of the step (first-order: none; a drive with a
    /// damping ratio of 0.8 overshoots by 1.5 %).
    pub overshoot_fraction: f64,
    /// Joint speeds under which the arm counts as at rest, per joint.
    pub rest_velocity: [f64; JOINT_COUNT],
    /// Longest wait for a set-point or a brake, and the streaming period (5 ms = 200 Hz).
    pub settle: PollBounds,
    /// Feedback samples read when checking stamps and standing still.
    pub samples: usize,
}

impl ServoConformanceConfig {
    /// Defaults around the given limits: steps of 5 cm and 0.1-0.3 rad, tolerances of 2 mm and
    /// 5 mrad, 10 % overshoot, 10 s settle bound, 200 Hz streaming.
    pub fn with_limits(limits: [[f64; 2]; JOINT_COUNT]) -> Self {
        Self {
            limits,
            step: [0.05, 0.1, 0.1, 0.3],
            tolerance: [0.002, 0.005, 0.005, 0.005],
            overshoot_fraction: 0.1,
            rest_velocity: [0.002, 0.005, 0.005, 0.005],
            settle: PollBounds {
                timeout: Duration::from_secs(10),
                interval: Duration::from_millis(5),
            },
            samples: 20,
        }
    }
}

/// Runs every check, each with a fresh driver from `make`.
pub fn conformance_suite<S: ArmServos>(
    config: &ServoConformanceConfig,
    make: impl FnMut() -> S,
) -> Result<ConformanceReport, ConformanceError> {
    let checks: [Check<ServoConformanceConfig, S>; 4] = [
        ("feedback_stamps_increase", check_feedback),
        ("setpoint_reached_first_order", check_setpoint),
        ("limits_refused", check_limits),
        ("hold_brakes_and_keeps_position", check_hold),
    ];
    run_checks("arm servos", config, &checks, make, |_, _| Ok(()))
}

/// The newest feedback, waiting (bounded) for the first sample.
fn feedback<S: ArmServos>(
    check: &'static str,
    config: &ServoConformanceConfig,
    servos: &mut S,
) -> Result<JointFeedback, ConformanceError> {
    poll_until(check, config.settle, "the first encoder sample", || {
        Ok(
            match call(check, || "feedback()".to_owned(), servos.feedback())? {
                Some(sample) => Probe::Done(sample),
                None => Probe::Waiting("no sample yet".to_owned()),
            },
        )
    })
}

/// Per joint, `from + step` when it stays inside the limits (less the tolerance), else
/// `from - step`, clamped inside.
fn target_from(
    config: &ServoConformanceConfig,
    from: [f64; JOINT_COUNT],
    scale: f64,
) -> [f64; JOINT_COUNT] {
    std::array::from_fn(|j| {
        let [min, max] = config.limits[j];
        let (lo, hi) = (min + config.tolerance[j], max - config.tolerance[j]);
        let step = config.step[j] * scale;
        let here = from[j].clamp(lo, hi);
        if here + step <= hi {
            here + step
        } else {
            (here - step).max(lo)
        }
    })
}

fn in_limits(config: &ServoConformanceConfig, sample: &JointFeedback) -> Result<(), String> {
    for (j, name) in JOINT_NAMES.iter().enumerate() {
        let [min, max] = config.limits[j];
        let q = sample.position[j];
        let slack = config.tolerance[j];
        if !q.is_finite() || q < min - slack || q > max + slack || !sample.velocity[j].is_finite() {
            return Err(format!(
                "joint {name} at {q} (rate {}) outside [{min}, {max}] or not finite",
                sample.velocity[j]
            ));
        }
    }
    Ok(())
}

/// Feedback is within limits; stamps never go back and advance over time.
fn check_feedback<S: ArmServos>(
    config: &ServoConformanceConfig,
    servos: &mut S,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "feedback_stamps_increase";
    stamps_advance(
        CHECK,
        config.settle,
        config.samples,
        "a newer encoder stamp",
        || feedback(CHECK, config, servos),
        |sample| sample.capture_ns,
        |sample| in_limits(config, sample),
    )
}

/// Streams `target` until every joint has been within tolerance for `config.samples`
/// consecutive samples; every sample must be approaching: never farther from the target than at
/// the start (plus tolerance), never past it by more than the allowed overshoot. Watching past
/// the first sample in tolerance catches a servo that runs through the target. Returns the last
/// sample.
fn stream_to<S: ArmServos>(
    check: &'static str,
    config: &ServoConformanceConfig,
    servos: &mut S,
    target: [f64; JOINT_COUNT],
) -> Result<JointFeedback, ConformanceError> {
    let start = feedback(check, config, servos)?.position;
    let mut last_stamp_ns = 0;
    let mut samples_in_tolerance = 0;
    poll_until(check, config.settle, "the set-point", || {
        call(
            check,
            || format!("command({target:?}, 0)"),
            servos.command(target, [0.0; JOINT_COUNT]),
        )?;
        let now = feedback(check, config, servos)?;
        if now.capture_ns < last_stamp_ns {
            return Err(violated(
                check,
                format!(
                    "stamp went back from {last_stamp_ns} to {} ns",
                    now.capture_ns
                ),
            ));
        }
        last_stamp_ns = now.capture_ns;
        let mut reached = true;
        for j in 0..JOINT_COUNT {
            let initial_error = target[j] - start[j];
            let error = target[j] - now.position[j];
            let tolerance = config.tolerance[j];
            let overshoot = -error * initial_error.signum();
            if error.abs() > initial_error.abs() + tolerance
                || overshoot > config.overshoot_fraction * initial_error.abs() + tolerance
            {
                return Err(violated(
                    check,
                    format!(
                        "joint {} at {} moving from {} to {}: not a first-order approach",
                        JOINT_NAMES[j], now.position[j], start[j], target[j]
                    ),
                ));
            }
            reached &= error.abs() <= tolerance;
        }
        samples_in_tolerance = if reached { samples_in_tolerance + 1 } else { 0 };
        Ok(if samples_in_tolerance >= config.samples.max(1) {
            Probe::Done(now)
        } else {
            Probe::Waiting(format!("at {:?}, target {target:?}", now.position))
        })
    })
}

/// A step on every joint is reached within tolerance with a first-order approach.
fn check_setpoint<S: ArmServos>(
    config: &ServoConformanceConfig,
    servos: &mut S,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "setpoint_reached_first_order";
    let start = feedback(CHECK, config, servos)?.position;
    let target = target_from(config, start, 1.0);
    stream_to(CHECK, config, servos, target).map(|_| ())
}

/// Waits until every joint rate is under `rest_velocity`; returns that sample.
fn wait_at_rest<S: ArmServos>(
    check: &'static str,
    config: &ServoConformanceConfig,
    servos: &mut S,
) -> Result<JointFeedback, ConformanceError> {
    poll_until(check, config.settle, "the arm at rest", || {
        let now = feedback(check, config, servos)?;
        let at_rest = (0..JOINT_COUNT).all(|j| now.velocity[j].abs() <= config.rest_velocity[j]);
        Ok(if at_rest {
            Probe::Done(now)
        } else {
            Probe::Waiting(format!("rates {:?}", now.velocity))
        })
    })
}

/// Over `samples` polls without commands, no joint moves beyond tolerance from `at`.
fn stays_put<S: ArmServos>(
    check: &'static str,
    config: &ServoConformanceConfig,
    servos: &mut S,
    at: [f64; JOINT_COUNT],
    after: &str,
) -> Result<(), ConformanceError> {
    for _ in 0..config.samples {
        std::thread::sleep(config.settle.interval);
        let now = feedback(check, config, servos)?;
        if let Some(j) =
            (0..JOINT_COUNT).find(|&j| (now.position[j] - at[j]).abs() > config.tolerance[j])
        {
            return Err(violated(
                check,
                format!(
                    "after {after}, joint {} moved from {} to {}",
                    JOINT_NAMES[j], at[j], now.position[j]
                ),
            ));
        }
    }
    Ok(())
}

/// Positions beyond either limit, NaN positions and infinite rates are refused with kind
/// `InvalidRequest`, on every joint, and the arm does not move.
fn check_limits<S: ArmServos>(
    config: &ServoConformanceConfig,
    servos: &mut S,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "limits_refused";
    call(CHECK, || "hold()".to_owned(), servos.hold())?;
    let here = wait_at_rest(CHECK, config, servos)?.position;
    let inside: [f64; JOINT_COUNT] = std::array::from_fn(|j| {
        let [min, max] = config.limits[j];
        here[j].clamp(min, max)
    });
    for j in 0..JOINT_COUNT {
        let [min, max] = config.limits[j];
        let margin = 0.1 * (max - min);
        for bad in [max + margin, min - margin, f64::NAN] {
            let mut position = inside;
            position[j] = bad;
            expect_refusal(
                CHECK,
                || format!("command with {} = {bad}", JOINT_NAMES[j]),
                ErrorKind::InvalidRequest,
                servos.command(position, [0.0; JOINT_COUNT]),
            )?;
        }
        let mut velocity = [0.0; JOINT_COUNT];
        velocity[j] = f64::INFINITY;
        expect_refusal(
            CHECK,
            || format!("command with {} rate = inf", JOINT_NAMES[j]),
            ErrorKind::InvalidRequest,
            servos.command(inside, velocity),
        )?;
    }
    stays_put(CHECK, config, servos, here, "refused set-points")
}

/// `hold` during a long move stops the arm short of its target; it then stays there.
fn check_hold<S: ArmServos>(
    config: &ServoConformanceConfig,
    servos: &mut S,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "hold_brakes_and_keeps_position";
    let start = feedback(CHECK, config, servos)?.position;
    let target = target_from(config, start, 4.0);
    // Stream until every joint covered a quarter of its way, then brake.
    poll_until(CHECK, config.settle, "a quarter of the move", || {
        call(
            CHECK,
            || format!("command({target:?}, 0)"),
            servos.command(target, [0.0; JOINT_COUNT]),
        )?;
        let now = feedback(CHECK, config, servos)?.position;
        let covered = (0..JOINT_COUNT)
            .all(|j| (now[j] - start[j]).abs() >= 0.25 * (target[j] - start[j]).abs());
        Ok(if covered {
            Probe::Done(())
        } else {
            Probe::Waiting(format!("at {now:?} from {start:?} to {target:?}"))
        })
    })?;
    call(CHECK, || "hold()".to_owned(), servos.hold())?;
    let braked = wait_at_rest(CHECK, config, servos)?.position;
    let short = (0..JOINT_COUNT).any(|j| (braked[j] - target[j]).abs() > config.tolerance[j]);
    if !short {
        return Err(violated(
            CHECK,
            format!("hold() did not brake: the arm reached {target:?} anyway"),
        ));
    }
    stays_put(CHECK, config, servos, braked, "hold()")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::DeviceError;

    /// What a deliberately broken servo gets wrong.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Flaw {
        None,
        /// Heads 30 % past every new set-point.
        Overshoots,
        /// Accepts set-points outside the limits.
        AcceptsAnything,
        /// `hold` does nothing.
        IgnoresHold,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("joint {joint} set-point {value} refused")]
    struct Refused {
        joint: usize,
        value: f64,
    }

    impl DeviceError for Refused {
        fn kind(&self) -> ErrorKind {
            ErrorKind::InvalidRequest
        }
    }

    /// First-order servos (time constant 20 ms) advanced by a fixed 1 ms on every call: on the
    /// host clock a loaded machine could pause between two calls for longer than the whole move,
    /// and a servo that ignores `hold` would then pass (or a correct one fail) the hold check.
    struct FirstOrderServos {
        limits: [[f64; 2]; JOINT_COUNT],
        position: [f64; JOINT_COUNT],
        velocity: [f64; JOINT_COUNT],
        goal: [f64; JOINT_COUNT],
        last_setpoint: [f64; JOINT_COUNT],
        stamp_ns: u64,
        flaw: Flaw,
    }

    impl FirstOrderServos {
        const TAU_S: f64 = 0.02;
        /// Simulated time per call.
        const STEP_S: f64 = 0.001;

        fn new(limits: [[f64; 2]; JOINT_COUNT], flaw: Flaw) -> Self {
            Self {
                limits,
                position: [0.0; JOINT_COUNT],
                velocity: [0.0; JOINT_COUNT],
                goal: [0.0; JOINT_COUNT],
                last_setpoint: [0.0; JOINT_COUNT],
                stamp_ns: 0,
                flaw,
            }
        }

        fn advance(&mut self) {
            let dt_s = Self::STEP_S;
            let decay = (-dt_s / Self::TAU_S).exp();
            for j in 0..JOINT_COUNT {
                let next = self.goal[j] + (self.position[j] - self.goal[j]) * decay;
                self.velocity[j] = (next - self.position[j]) / dt_s;
                self.position[j] = next;
            }
            self.stamp_ns += 1_000;
        }
    }

    impl ArmServos for FirstOrderServos {
        type Error = Refused;

        fn command(
            &mut self,
            position: [f64; JOINT_COUNT],
            velocity: [f64; JOINT_COUNT],
        ) -> Result<(), Refused> {
            for j in 0..JOINT_COUNT {
                let [min, max] = self.limits[j];
                let ok = (min..=max).contains(&position[j]) && velocity[j].is_finite();
                if !ok && self.flaw != Flaw::AcceptsAnything {
                    return Err(Refused {
                        joint: j,
                        value: position[j],
                    });
                }
            }
            self.advance();
            if position != self.last_setpoint {
                self.last_setpoint = position;
                self.goal = std::array::from_fn(|j| match self.flaw {
                    Flaw::Overshoots => position[j] + 0.3 * (position[j] - self.position[j]),
                    _ => position[j],
                });
            }
            Ok(())
        }

        fn hold(&mut self) -> Result<(), Refused> {
            self.advance();
            if self.flaw != Flaw::IgnoresHold {
                self.goal = self.position;
                self.last_setpoint = [f64::NAN; JOINT_COUNT];
            }
            Ok(())
        }

        fn feedback(&mut self) -> Result<Option<JointFeedback>, Refused> {
            self.advance();
            Ok(Some(JointFeedback {
                capture_ns: self.stamp_ns,
                position: self.position,
                velocity: self.velocity,
                fault_bits: 0,
            }))
        }
    }

    const LIMITS: [[f64; 2]; JOINT_COUNT] = [[-0.02, 0.6], [-0.3, 0.5], [-0.3, 0.3], [-3.1, 3.1]];

    fn run(flaw: Flaw) -> Result<ConformanceReport, ConformanceError> {
        let config = ServoConformanceConfig::with_limits(LIMITS);
        conformance_suite(&config, || FirstOrderServos::new(LIMITS, flaw))
    }

    fn failed_check(result: Result<ConformanceReport, ConformanceError>) -> &'static str {
        match result {
            Err(ConformanceError::Violated { check, .. })
            | Err(ConformanceError::WrongOutcome { check, .. })
            | Err(ConformanceError::CallFailed { check, .. }) => check,
            Ok(report) => panic!("a broken servo passed: {report:?}"),
        }
    }

    #[test]
    fn a_first_order_servo_passes_and_broken_ones_fail_the_right_check() {
        let report = run(Flaw::None).expect("first-order servos conform");
        assert_eq!(report.checks_passed.len(), 4);
        assert_eq!(
            failed_check(run(Flaw::Overshoots)),
            "setpoint_reached_first_order"
        );
        assert_eq!(failed_check(run(Flaw::AcceptsAnything)), "limits_refused");
        assert_eq!(
            failed_check(run(Flaw::IgnoresHold)),
            "hold_brakes_and_keeps_position"
        );
    }

    #[test]
    fn targets_stay_inside_the_limits() {
        let config = ServoConformanceConfig::with_limits([
            [-0.02, 0.6],
            [-0.3, 0.5],
            [-0.3, 0.3],
            [-3.1, 3.1],
        ]);
        let target = target_from(&config, [0.0, 0.0, 0.29, 3.1], 1.0);
        assert!((target[0] - 0.05).abs() < 1e-12);
        assert!((target[1] - 0.1).abs() < 1e-12);
        // Near the upper limit the step goes down.
        assert!((target[2] - (0.29 - 0.1)).abs() < 1e-12);
        assert!((target[3] - (3.095 - 0.3)).abs() < 1e-12);
        let far = target_from(&config, [0.0; JOINT_COUNT], 100.0);
        for j in 0..JOINT_COUNT {
            let [min, max] = config.limits[j];
            assert!((min..=max).contains(&far[j]), "{far:?}");
        }
    }
}
