//! The scaffolding of a periodic control loop: a wait set that wakes on a tick interval and on
//! the heartbeat interval, with the tick-to-tick intervals recorded ([`PeriodStats`]).
//!
//! The arm and vacuum processes run this way at 200 Hz (paper 003, section 2.2): each tick is a
//! wait-set interval, never a sleep, and every heartbeat carries the period distribution so
//! far. The loop ends on SIGINT/SIGTERM, when the callback returns [`Flow::Stop`], or with the
//! callback's error.

use std::time::Duration;

use crate::error::WaitError;
use crate::{Flow, HEARTBEAT_PERIOD, MonotonicClock, RunError, Waiter};

use crate::period_stats::{PeriodStats, PeriodStatsError, PeriodSummary};

/// Why the control loop woke up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Wake {
    /// A control tick, read from the monotonic clock (already recorded in the period
    /// statistics).
    Tick { now_ns: u64 },
    /// Time for a heartbeat; `period` is the tick-to-tick distribution so far.
    Heartbeat { period: PeriodSummary },
}

/// Runs `on_wake` every `period_ns` ([`Wake::Tick`]) and every [`HEARTBEAT_PERIOD`]
/// ([`Wake::Heartbeat`]) until a signal, a [`Flow::Stop`] or an error; returns the distribution
/// of the tick-to-tick intervals.
pub fn run_control_loop<E>(
    period_ns: u64,
    mut on_wake: impl FnMut(Wake) -> Result<Flow, E>,
) -> Result<PeriodSummary, E>
where
    E: From<PeriodStatsError> + From<WaitError>,
{
    let mut period = PeriodStats::new(period_ns)?;
    let waiter = Waiter::new()?;
    let tick = waiter.attach_interval(Duration::from_nanos(period_ns))?;
    let heartbeat = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    waiter
        .run(|attachment| {
            if attachment.has_event_from(&tick) {
                let now_ns = MonotonicClock::read_ns();
                period.tick(now_ns);
                return on_wake(Wake::Tick { now_ns });
            }
            if attachment.has_event_from(&heartbeat) {
                return on_wake(Wake::Heartbeat {
                    period: period.summary(),
                });
            }
            Ok(Flow::Continue)
        })
        .map_err(RunError::flatten)?;
    Ok(period.summary())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    enum TestError {
        #[error(transparent)]
        Period(#[from] PeriodStatsError),
        #[error(transparent)]
        Wait(#[from] WaitError),
        #[error("stopped by the callback")]
        Callback,
    }

    #[test]
    fn records_every_tick_until_stopped() {
        let mut stamps_ns = Vec::new();
        let summary = run_control_loop(1_000_000, |wake| -> Result<Flow, TestError> {
            if let Wake::Tick { now_ns } = wake {
                stamps_ns.push(now_ns);
            }
            Ok(if stamps_ns.len() == 5 {
                Flow::Stop
            } else {
                Flow::Continue
            })
        })
        .expect("loop");
        assert_eq!(stamps_ns.len(), 5);
        assert!(stamps_ns.windows(2).all(|pair| pair[0] <= pair[1]));
        // Five ticks: four intervals.
        assert_eq!(summary.ticks, 4);
        assert_eq!(summary.nominal_ns, 1_000_000);
    }

    #[test]
    fn a_callback_error_ends_the_loop() {
        let result = run_control_loop(1_000_000, |_| Err(TestError::Callback));
        assert!(matches!(result, Err(TestError::Callback)));
    }

    #[test]
    fn a_zero_period_is_refused() {
        let result = run_control_loop(0, |_| Ok::<_, TestError>(Flow::Stop));
        assert!(matches!(
            result,
            Err(TestError::Period(PeriodStatsError::ZeroPeriod))
        ));
    }
}
