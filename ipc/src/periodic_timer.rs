//! The tick source of the control loops: a kernel periodic timer (`timerfd` on
//! `CLOCK_MONOTONIC`) the loop blocks on.
//!
//! Why not a wait-set interval: iceoryx2's wait set sleeps in `epoll_wait`, whose timeout is in
//! milliseconds and is rounded up, so a 5 ms interval wakes up to 1 ms late (measured on this
//! stack: `|period - 5 ms|` p99 0.93 ms with SCHED_FIFO); and each wake-up of the wait set
//! allocates. The timer's expirations follow a fixed schedule (each one a period after the
//! previous one, not after the wake-up), are delivered with high-resolution timer precision,
//! and a read returns how many passed: a loop that was held up learns how many ticks it missed.

use std::time::Duration;

use nix::errno::Errno;
use nix::sys::time::TimeSpec;
use nix::sys::timerfd::{ClockId, Expiration, TimerFd, TimerFlags, TimerSetTimeFlags};

/// The timer could not be set up or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PeriodicTimerError {
    /// The period is zero.
    #[error("timer period must be > 0")]
    ZeroPeriod,
    /// `timerfd_create` or `timerfd_settime` failed.
    #[error("cannot set up the periodic timer: {0}")]
    Setup(Errno),
    /// Reading the expiration count failed.
    #[error("cannot read the periodic timer: {0}")]
    Read(Errno),
}

/// What [`PeriodicTimer::wait`] returned on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimerWake {
    /// One or more ticks are due: `elapsed` expirations since the previous wait (1 when the
    /// caller kept up; more when it was held up past the next tick).
    Tick {
        /// Timer expirations since the previous wait.
        elapsed: u64,
    },
    /// A signal interrupted the wait before a tick (check for a termination request).
    Interrupted,
}

/// A periodic timer on `CLOCK_MONOTONIC`, first tick one period after creation.
#[derive(Debug)]
pub struct PeriodicTimer {
    fd: TimerFd,
    period: Duration,
}

impl PeriodicTimer {
    /// Starts the timer.
    pub fn new(period: Duration) -> Result<Self, PeriodicTimerError> {
        if period.is_zero() {
            return Err(PeriodicTimerError::ZeroPeriod);
        }
        let fd = TimerFd::new(ClockId::CLOCK_MONOTONIC, TimerFlags::TFD_CLOEXEC)
            .map_err(PeriodicTimerError::Setup)?;
        let spec = TimeSpec::from_duration(period);
        fd.set(
            Expiration::IntervalDelayed(spec, spec),
            TimerSetTimeFlags::empty(),
        )
        .map_err(PeriodicTimerError::Setup)?;
        Ok(Self { fd, period })
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// Blocks until the next tick (returns at once if ticks passed since the last call).
    /// Makes one `read` system call and does not allocate.
    pub fn wait(&self) -> Result<TimerWake, PeriodicTimerError> {
        let mut count = [0u8; 8];
        match nix::unistd::read(&self.fd, &mut count) {
            Ok(8) => Ok(TimerWake::Tick {
                elapsed: u64::from_ne_bytes(count),
            }),
            // A timerfd read returns 8 bytes or fails; anything else is treated as no tick.
            Ok(_) => Ok(TimerWake::Interrupted),
            Err(Errno::EINTR) => Ok(TimerWake::Interrupted),
            Err(errno) => Err(PeriodicTimerError::Read(errno)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MonotonicClock;

    fn elapsed(wake: TimerWake) -> u64 {
        match wake {
            TimerWake::Tick { elapsed } => elapsed,
            TimerWake::Interrupted => panic!("no signal was sent"),
        }
    }

    #[test]
    fn ticks_follow_the_period_and_count_missed_ones() {
        let period_ns = 2_000_000;
        let timer = PeriodicTimer::new(Duration::from_nanos(period_ns)).expect("timer");
        assert_eq!(timer.period(), Duration::from_nanos(period_ns));
        let start_ns = MonotonicClock::read_ns();
        let mut expirations = 0;
        for _ in 0..3 {
            let count = elapsed(timer.wait().expect("wait"));
            // Each wait returns on a tick (more than one if this thread was held up).
            assert!(count >= 1);
            expirations += count;
        }
        // Never ahead of the schedule: n expirations take at least n periods.
        assert!(MonotonicClock::read_ns() - start_ns >= expirations * period_ns);
        // Held up for more than two periods: the next wait returns at once with the count.
        std::thread::sleep(Duration::from_millis(5));
        let count = elapsed(timer.wait().expect("wait"));
        assert!(count >= 2, "{count}");
    }

    #[test]
    fn a_zero_period_is_refused() {
        assert_eq!(
            PeriodicTimer::new(Duration::ZERO).err(),
            Some(PeriodicTimerError::ZeroPeriod)
        );
    }
}
