//! Behaviour every [`Platform`] implementation must show, written once and generic over the
//! trait (harness: [`crate::conformance`]). Run it with a factory of fresh drivers:
//!
//! ```ignore
//! let report = conformance_suite(&PlatformConformanceConfig::default(), || connect())?;
//! ```
//!
//! The drivers may share one physical (or simulated) platform: every check first waits until
//! the stages stand still. The moves are small (a few centimetres) so the suite runs in seconds
//! on slow stepper stages; each check is bounded by [`PlatformConformanceConfig::settle`].

use super::{Platform, PlatformAxis, PlatformPosition, PlatformTravel};
use crate::conformance::{
    Check, ConformanceError, ConformanceReport, PollBounds, Probe, call, expect_refusal,
    poll_until, run_checks, stamps_advance, violated,
};
use crate::error_kind::ErrorKind;
use std::time::Duration;

/// Bounds and sizes of the platform checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformConformanceConfig {
    /// Longest wait for a move or a stop to settle, and the polling period.
    pub settle: PollBounds,
    /// Largest distance between a settled stage and its target, and the slack allowed on
    /// "between start and target" while moving, m (the encoders' resolution plus margin).
    pub position_tolerance_m: f64,
    /// Size of the test move on each axis, m (must take longer than one poll to travel).
    pub step_m: f64,
    /// Size of the move that is stopped half-way, m.
    pub long_step_m: f64,
    /// Distance the stopped move must have covered before `stop` is sent, m.
    pub moved_before_stop_m: f64,
    /// Feedback samples read when checking stamps and standing still.
    pub samples: usize,
}

impl Default for PlatformConformanceConfig {
    fn default() -> Self {
        Self {
            settle: PollBounds {
                timeout: Duration::from_secs(20),
                interval: Duration::from_millis(10),
            },
            position_tolerance_m: 1e-3,
            step_m: 0.03,
            long_step_m: 0.15,
            moved_before_stop_m: 0.005,
            samples: 20,
        }
    }
}

/// Runs every check, each with a fresh driver from `make`.
pub fn conformance_suite<P: Platform>(
    config: &PlatformConformanceConfig,
    make: impl FnMut() -> P,
) -> Result<ConformanceReport, ConformanceError> {
    let checks: [Check<PlatformConformanceConfig, P>; 5] = [
        ("feedback_live_and_in_travel", check_feedback),
        ("move_reaches_target_without_overshoot", check_move),
        ("refuses_targets_outside_travel", check_refusals),
        ("travel_ends_accepted", check_travel_ends),
        ("stop_halts_motion", check_stop),
    ];
    run_checks("platform", config, &checks, make, |_, _| Ok(()))
}

fn position<P: Platform>(
    check: &'static str,
    platform: &mut P,
) -> Result<PlatformPosition, ConformanceError> {
    call(check, || "position()".to_owned(), platform.position())
}

fn as_array(position: &PlatformPosition) -> [f64; 2] {
    [position.in_out_m, position.up_down_m]
}

/// Waits until the stages report standing still; returns where.
fn settle<P: Platform>(
    check: &'static str,
    config: &PlatformConformanceConfig,
    platform: &mut P,
) -> Result<PlatformPosition, ConformanceError> {
    poll_until(check, config.settle, "stages standing still", || {
        let now = position(check, platform)?;
        Ok(if now.in_motion {
            Probe::Waiting(format!("{now:?}"))
        } else {
            Probe::Done(now)
        })
    })
}

/// A target `step_m` away from `from_m` on each axis, inside the travel (the direction with
/// more room).
fn target_within(travel: &PlatformTravel, from_m: [f64; 2], step_m: f64) -> [f64; 2] {
    PlatformAxis::ALL.map(|axis| {
        let here = from_m[axis.index()];
        let max = travel.max_m(axis);
        if max - here >= here {
            (here + step_m).min(max)
        } else {
            (here - step_m).max(0.0)
        }
    })
}

/// Waits until the stages stand still, then starts a move of `step_m` on each axis (inside the
/// travel); returns where it started and its target, m.
fn start_move<P: Platform>(
    check: &'static str,
    config: &PlatformConformanceConfig,
    platform: &mut P,
    step_m: f64,
) -> Result<([f64; 2], [f64; 2]), ConformanceError> {
    let start = as_array(&settle(check, config, platform)?);
    let target = target_within(&platform.travel(), start, step_m);
    call(
        check,
        || format!("move_to({}, {})", target[0], target[1]),
        platform.move_to(target[0], target[1]),
    )?;
    Ok((start, target))
}

/// Positions finite and in the travel; stamps never go back and do advance.
fn check_feedback<P: Platform>(
    config: &PlatformConformanceConfig,
    platform: &mut P,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "feedback_live_and_in_travel";
    let travel = platform.travel();
    if !travel.is_valid() {
        return Err(violated(
            CHECK,
            format!("declared travel {travel:?} is empty"),
        ));
    }
    stamps_advance(
        CHECK,
        config.settle,
        config.samples,
        "a newer feedback stamp",
        || position(CHECK, platform),
        |now| now.capture_ns,
        |now| in_travel(config, &travel, now),
    )
}

/// Both positions finite and inside the travel (plus the tolerance).
fn in_travel(
    config: &PlatformConformanceConfig,
    travel: &PlatformTravel,
    now: &PlatformPosition,
) -> Result<(), String> {
    for axis in PlatformAxis::ALL {
        let value_m = as_array(now)[axis.index()];
        let slack = config.position_tolerance_m;
        if !value_m.is_finite() || value_m < -slack || value_m > travel.max_m(axis) + slack {
            return Err(format!(
                "{axis} position {value_m} m outside travel {travel:?}"
            ));
        }
    }
    Ok(())
}

/// A move reports `in_motion` at once, approaches the target on both axes without leaving the
/// segment from start to target (rate-limited / first-order motion never overshoots), and
/// settles within tolerance.
fn check_move<P: Platform>(
    config: &PlatformConformanceConfig,
    platform: &mut P,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "move_reaches_target_without_overshoot";
    let (start, target) = start_move(CHECK, config, platform, config.step_m)?;
    let first = position(CHECK, platform)?;
    if !first.in_motion {
        return Err(violated(
            CHECK,
            format!("first position after move_to({target:?}) reports standing still: {first:?}"),
        ));
    }
    let tolerance = config.position_tolerance_m;
    let settled = poll_until(CHECK, config.settle, "the move settled", || {
        let now = position(CHECK, platform)?;
        for axis in PlatformAxis::ALL {
            let i = axis.index();
            let (lo, hi) = (start[i].min(target[i]), start[i].max(target[i]));
            let value = as_array(&now)[i];
            if value < lo - tolerance || value > hi + tolerance {
                return Err(violated(
                    CHECK,
                    format!(
                        "{axis} at {value} m left the segment from {} m to {} m",
                        start[i], target[i]
                    ),
                ));
            }
        }
        Ok(if now.in_motion {
            Probe::Waiting(format!("{now:?}"))
        } else {
            Probe::Done(now)
        })
    })?;
    for axis in PlatformAxis::ALL {
        let i = axis.index();
        let error_m = (as_array(&settled)[i] - target[i]).abs();
        if error_m > tolerance {
            return Err(violated(
                CHECK,
                format!(
                    "{axis} settled {error_m} m from its target {} m (tolerance {tolerance} m)",
                    target[i]
                ),
            ));
        }
    }
    Ok(())
}

/// Checks that the stages stand still within tolerance of `at` over `samples` polls.
fn stays_put<P: Platform>(
    check: &'static str,
    config: &PlatformConformanceConfig,
    platform: &mut P,
    at: [f64; 2],
    after: &str,
) -> Result<(), ConformanceError> {
    for _ in 0..config.samples {
        let now = position(check, platform)?;
        let drift_m =
            PlatformAxis::ALL.map(|axis| (as_array(&now)[axis.index()] - at[axis.index()]).abs());
        if now.in_motion || drift_m.iter().any(|d| *d > config.position_tolerance_m) {
            return Err(violated(
                check,
                format!("after {after} the stages moved from {at:?} m: {now:?}"),
            ));
        }
        std::thread::sleep(config.settle.interval);
    }
    Ok(())
}

/// Targets below 0, beyond the stroke or not finite, on either axis, fail with
/// `InvalidRequest` and leave the stages standing where they were.
fn check_refusals<P: Platform>(
    config: &PlatformConformanceConfig,
    platform: &mut P,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "refuses_targets_outside_travel";
    let start = as_array(&settle(CHECK, config, platform)?);
    let travel = platform.travel();
    let beyond = [travel.in_out_max_m + 0.01, travel.up_down_max_m + 0.01];
    let bad_targets = [
        [-0.01, start[1]],
        [beyond[0], start[1]],
        [start[0], -0.01],
        [start[0], beyond[1]],
        [f64::NAN, start[1]],
        [start[0], f64::INFINITY],
    ];
    for [in_out, up_down] in bad_targets {
        expect_refusal(
            CHECK,
            || format!("move_to({in_out}, {up_down})"),
            ErrorKind::InvalidRequest,
            platform.move_to(in_out, up_down),
        )?;
    }
    stays_put(CHECK, config, platform, start, "refused targets")
}

/// Both ends of the travel are valid targets (the stops are inclusive).
fn check_travel_ends<P: Platform>(
    config: &PlatformConformanceConfig,
    platform: &mut P,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "travel_ends_accepted";
    settle(CHECK, config, platform)?;
    let travel = platform.travel();
    for [in_out, up_down] in [[0.0, 0.0], [travel.in_out_max_m, travel.up_down_max_m]] {
        call(
            CHECK,
            || format!("move_to({in_out}, {up_down})"),
            platform.move_to(in_out, up_down),
        )?;
    }
    call(CHECK, || "stop()".to_owned(), platform.stop())?;
    settle(CHECK, config, platform).map(|_| ())
}

/// A long move stopped half-way ends short of its target, between start and target, and the
/// stages then stay there.
fn check_stop<P: Platform>(
    config: &PlatformConformanceConfig,
    platform: &mut P,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "stop_halts_motion";
    let (start, target) = start_move(CHECK, config, platform, config.long_step_m)?;
    poll_until(CHECK, config.settle, "motion under way", || {
        let now = as_array(&position(CHECK, platform)?);
        let moved_m = (now[0] - start[0]).abs().max((now[1] - start[1]).abs());
        Ok(if moved_m >= config.moved_before_stop_m {
            Probe::Done(())
        } else {
            Probe::Waiting(format!("moved {moved_m} m from {start:?}"))
        })
    })?;
    call(CHECK, || "stop()".to_owned(), platform.stop())?;
    let stopped = as_array(&settle(CHECK, config, platform)?);
    let tolerance = config.position_tolerance_m;
    let short_of_target = PlatformAxis::ALL
        .iter()
        .any(|axis| (stopped[axis.index()] - target[axis.index()]).abs() > tolerance);
    if !short_of_target {
        return Err(violated(
            CHECK,
            format!("stop() did not halt the move: reached the target {target:?} m anyway"),
        ));
    }
    for axis in PlatformAxis::ALL {
        let i = axis.index();
        let (lo, hi) = (start[i].min(target[i]), start[i].max(target[i]));
        if stopped[i] < lo - tolerance || stopped[i] > hi + tolerance {
            return Err(violated(
                CHECK,
                format!("{axis} stopped at {} m, outside [{lo}, {hi}] m", stopped[i]),
            ));
        }
    }
    stays_put(CHECK, config, platform, stopped, "stop()")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn test_targets_stay_inside_the_travel() {
        let travel = PlatformTravel::default();
        assert_eq!(target_within(&travel, [0.0, 0.0], 0.03), [0.03, 0.03]);
        assert_eq!(target_within(&travel, [0.5, 0.8], 0.03), [0.47, 0.77]);
        let long = target_within(&travel, [0.1, 0.7], 1.0);
        assert_eq!(long, [0.5, 0.0]);
    }
}
