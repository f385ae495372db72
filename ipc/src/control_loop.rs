//! The scaffolding of a periodic control loop: ticks from a kernel periodic timer
//! ([`PeriodicTimer`]), a heartbeat every [`HEARTBEAT_PERIOD`], the tick-to-tick intervals
//! recorded ([`PeriodStats`]).
//!
//! The arm and vacuum processes run this way at 200 Hz ([dual-arm sec. 2.2]): each tick is a
//! timer expiration on a fixed schedule, never a sleep, and every heartbeat carries the period
//! distribution so far. The loop ends on SIGINT/SIGTERM, when the callback returns
//! [`Flow::Stop`], or with the callback's error.
//!
//! What happens in a tick is the caller's; what the loop itself does per tick is one `read` of
//! the timer, one clock read and one histogram record: no allocation, no lock but the signal
//! flag's, no logging. Before the first tick the loop locks the process's memory if the launch
//! file asked for it ([`memory_lock::lock_if_requested`]): everything the caller built before
//! calling (ports, node, buffers) and the histogram are faulted in and locked by then.
//!
//! The loop blocks on its timer rather than on a wait set ([`crate::periodic_timer`] says why);
//! it checks iceoryx2's termination flag (the one its wait sets use, so SIGINT/SIGTERM is seen
//! whichever part of iceoryx2 installed the handler) after each wake-up: a termination signal
//! interrupts the wait at once.

use std::time::Duration;

use iceoryx2_bb_posix::signal::SignalHandler;

use crate::error::WaitError;
use crate::memory_lock;
use crate::periodic_timer::{PeriodicTimer, TimerWake};
use crate::{Flow, HEARTBEAT_PERIOD, MonotonicClock};

use crate::period_stats::{PeriodStats, PeriodStatsError, PeriodSummary};

/// Why the control loop woke up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Wake {
    /// A control tick, read from the monotonic clock (already recorded in the period
    /// statistics).
    Tick {
        /// The tick time, ns on the monotonic stack clock.
        now_ns: u64,
    },
    /// Time for a heartbeat (right after a tick); `period` is the tick-to-tick distribution so
    /// far, with the deadline misses.
    Heartbeat {
        /// Tick-to-tick periods since start.
        period: PeriodSummary,
    },
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
    let timer = PeriodicTimer::new(Duration::from_nanos(period_ns)).map_err(wait_error)?;
    // Registers iceoryx2's SIGINT/SIGTERM handler if nothing did yet.
    if SignalHandler::termination_requested() {
        return Ok(period.summary());
    }
    let heartbeat_ns = HEARTBEAT_PERIOD.as_nanos() as u64;
    let mut next_heartbeat_ns = MonotonicClock::read_ns() + heartbeat_ns;
    memory_lock::lock_if_requested();
    loop {
        let wake = timer.wait().map_err(wait_error)?;
        if SignalHandler::termination_requested() {
            break;
        }
        let TimerWake::Tick { .. } = wake else {
            continue;
        };
        let now_ns = MonotonicClock::read_ns();
        period.tick(now_ns);
        if on_wake(Wake::Tick { now_ns })? == Flow::Stop {
            break;
        }
        if now_ns >= next_heartbeat_ns {
            next_heartbeat_ns = now_ns + heartbeat_ns;
            let summary = period.summary();
            if on_wake(Wake::Heartbeat { period: summary })? == Flow::Stop {
                break;
            }
        }
    }
    Ok(period.summary())
}

fn wait_error(error: crate::periodic_timer::PeriodicTimerError) -> WaitError {
    WaitError {
        reason: error.to_string(),
    }
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
    fn heartbeats_come_between_ticks_with_the_distribution() {
        let mut ticks = 0u64;
        let mut heartbeat = None;
        run_control_loop(10_000_000, |wake| -> Result<Flow, TestError> {
            match wake {
                Wake::Tick { .. } => ticks += 1,
                Wake::Heartbeat { period } => heartbeat = Some((ticks, period)),
            }
            Ok(if heartbeat.is_some() {
                Flow::Stop
            } else {
                Flow::Continue
            })
        })
        .expect("loop");
        let (ticks_before, period) = heartbeat.expect("a heartbeat");
        // 500 ms at 10 ms: the heartbeat comes after a tick, never before the first.
        assert!(ticks_before >= 1);
        assert_eq!(period.ticks, ticks_before - 1);
        assert_eq!(period.nominal_ns, 10_000_000);
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
