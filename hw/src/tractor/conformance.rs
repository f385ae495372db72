//! Behaviour every [`Tractor`] implementation must show, written once and generic over the
//! trait (harness: [`crate::conformance`]). Run it with a factory of fresh drivers:
//!
//! ```ignore
//! let report = conformance_suite(&TractorConformanceConfig::default(), || connect())?;
//! ```
//!
//! The drivers may share one tractor: every check first waits until it stands still. The
//! tractor only drives forward, so the suite needs `3 * step_m + long_step_m` of row left.

use super::{Tractor, TractorPosition};
use crate::conformance::{
    Check, ConformanceError, ConformanceReport, PollBounds, Probe, call, expect_refusal,
    poll_until, run_checks, stamps_advance, violated,
};
use crate::error_kind::ErrorKind;
use std::time::Duration;

/// Bounds and sizes of the tractor checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TractorConformanceConfig {
    /// Longest wait for a move or a stop to settle, and the polling period.
    pub settle: PollBounds,
    /// Largest distance between a settled trailer and its target, m.
    pub position_tolerance_m: f64,
    /// Size of the test advance, m.
    pub step_m: f64,
    /// Size of the advance that is stopped half-way, m.
    pub long_step_m: f64,
    /// Distance the stopped advance must have covered before `stop` is sent, m.
    pub moved_before_stop_m: f64,
    /// Feedback samples read when checking stamps and standing still.
    pub samples: usize,
}

impl Default for TractorConformanceConfig {
    fn default() -> Self {
        Self {
            settle: PollBounds {
                timeout: Duration::from_secs(20),
                interval: Duration::from_millis(10),
            },
            position_tolerance_m: 1e-3,
            step_m: 0.1,
            long_step_m: 0.6,
            moved_before_stop_m: 0.02,
            samples: 20,
        }
    }
}

/// Runs every check, each with a fresh driver from `make`.
pub fn conformance_suite<T: Tractor>(
    config: &TractorConformanceConfig,
    make: impl FnMut() -> T,
) -> Result<ConformanceReport, ConformanceError> {
    let checks: [Check<TractorConformanceConfig, T>; 4] = [
        ("feedback_live_and_on_the_row", check_feedback),
        ("advance_reaches_target_forward_only", check_advance),
        ("refuses_impossible_advances", check_refusals),
        ("stop_halts_motion", check_stop),
    ];
    run_checks("tractor", config, &checks, make, |_, _| Ok(()))
}

fn position<T: Tractor>(
    check: &'static str,
    tractor: &mut T,
) -> Result<TractorPosition, ConformanceError> {
    call(check, || "position()".to_owned(), tractor.position())
}

fn settle<T: Tractor>(
    check: &'static str,
    config: &TractorConformanceConfig,
    tractor: &mut T,
) -> Result<TractorPosition, ConformanceError> {
    poll_until(check, config.settle, "tractor standing still", || {
        let now = position(check, tractor)?;
        Ok(if now.in_motion {
            Probe::Waiting(format!("{now:?}"))
        } else {
            Probe::Done(now)
        })
    })
}

/// Position finite and not past the end of the row; stamps never go back and do advance.
fn check_feedback<T: Tractor>(
    config: &TractorConformanceConfig,
    tractor: &mut T,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "feedback_live_and_on_the_row";
    stamps_advance(
        CHECK,
        config.settle,
        config.samples,
        "a newer feedback stamp",
        || position(CHECK, tractor),
        |now| now.capture_ns,
        |now| {
            if now.position_m.is_finite()
                && now.position_m <= now.row_end_m + config.position_tolerance_m
            {
                Ok(())
            } else {
                Err(format!("position outside the row: {now:?}"))
            }
        },
    )
}

/// An advance reports `in_motion` at once, never goes backward nor past its target, and
/// settles on the target.
fn check_advance<T: Tractor>(
    config: &TractorConformanceConfig,
    tractor: &mut T,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "advance_reaches_target_forward_only";
    let start = settle(CHECK, config, tractor)?.position_m;
    let target = start + config.step_m;
    call(
        CHECK,
        || format!("advance({})", config.step_m),
        tractor.advance(config.step_m),
    )?;
    let first = position(CHECK, tractor)?;
    if !first.in_motion {
        return Err(violated(
            CHECK,
            format!("first position after advance reports standing still: {first:?}"),
        ));
    }
    let tolerance = config.position_tolerance_m;
    let mut last = start;
    let settled = poll_until(CHECK, config.settle, "the advance settled", || {
        let now = position(CHECK, tractor)?;
        if now.position_m < last - tolerance || now.position_m > target + tolerance {
            return Err(violated(
                CHECK,
                format!(
                    "trailer at {} m after {last} m: backward or past the target {target} m",
                    now.position_m
                ),
            ));
        }
        last = now.position_m;
        Ok(if now.in_motion {
            Probe::Waiting(format!("{now:?}"))
        } else {
            Probe::Done(now)
        })
    })?;
    if (settled.position_m - target).abs() > tolerance {
        return Err(violated(
            CHECK,
            format!("settled at {} m, target {target} m", settled.position_m),
        ));
    }
    Ok(())
}

/// Negative, non-finite and past-the-end advances fail with `InvalidRequest`; the trailer
/// stays where it was.
fn check_refusals<T: Tractor>(
    config: &TractorConformanceConfig,
    tractor: &mut T,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "refuses_impossible_advances";
    let start = settle(CHECK, config, tractor)?;
    let past_end = start.row_end_m - start.position_m + 0.01;
    for distance in [-0.1, f64::NAN, f64::INFINITY, past_end] {
        expect_refusal(
            CHECK,
            || format!("advance({distance})"),
            ErrorKind::InvalidRequest,
            tractor.advance(distance),
        )?;
    }
    for _ in 0..config.samples {
        let now = position(CHECK, tractor)?;
        if now.in_motion || (now.position_m - start.position_m).abs() > config.position_tolerance_m
        {
            return Err(violated(
                CHECK,
                format!("after refused advances the trailer moved from {start:?}: {now:?}"),
            ));
        }
        std::thread::sleep(config.settle.interval);
    }
    Ok(())
}

/// A long advance stopped under way ends short of its target and stays there.
fn check_stop<T: Tractor>(
    config: &TractorConformanceConfig,
    tractor: &mut T,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "stop_halts_motion";
    let start = settle(CHECK, config, tractor)?.position_m;
    let target = start + config.long_step_m;
    call(
        CHECK,
        || format!("advance({})", config.long_step_m),
        tractor.advance(config.long_step_m),
    )?;
    poll_until(CHECK, config.settle, "motion under way", || {
        let now = position(CHECK, tractor)?.position_m;
        Ok(if now - start >= config.moved_before_stop_m {
            Probe::Done(())
        } else {
            Probe::Waiting(format!("moved {} m from {start} m", now - start))
        })
    })?;
    call(CHECK, || "stop()".to_owned(), tractor.stop())?;
    let stopped = settle(CHECK, config, tractor)?.position_m;
    if stopped >= target - config.position_tolerance_m || stopped < start {
        return Err(violated(
            CHECK,
            format!("stop() did not halt the advance from {start} m to {target} m: at {stopped} m"),
        ));
    }
    Ok(())
}
