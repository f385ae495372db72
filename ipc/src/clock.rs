//! The one clock convention of the stack.
//!
//! Every `*_ns` stamp in a message header is nanoseconds of `CLOCK_MONOTONIC` on the host that
//! runs the stack (the same clock in every process on that host, not affected by wall-clock
//! jumps). Under a simulated clock (in-process evaluation, replay with a clock of its own) the same
//! fields hold simulated nanoseconds. Wall-clock time only appears in recordings' metadata, which
//! stores one (monotonic, realtime) pair so readers can convert.
//!
//! Process logic never reads a clock itself: it is handed a [`Clock`], so the same code runs live,
//! under a simulated clock, and against a replayed recording.

use nix::time::{ClockId, clock_gettime};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// A source of "now" in nanoseconds (see the module docs for which clock).
pub trait Clock {
    /// Now, nanoseconds.
    fn now_ns(&self) -> u64;
}

/// `CLOCK_MONOTONIC`, shared by all processes on a host.
#[derive(Debug, Clone, Copy, Default)]
pub struct MonotonicClock;

impl MonotonicClock {
    /// Reads `CLOCK_MONOTONIC` directly.
    pub fn read_ns() -> u64 {
        match clock_gettime(ClockId::CLOCK_MONOTONIC) {
            // The monotonic clock counts from boot: both fields are non-negative.
            Ok(now) => now.tv_sec() as u64 * 1_000_000_000 + now.tv_nsec() as u64,
            // `clock_gettime` fails only for a clock id the kernel does not know (EINVAL), and
            // every Linux kernel knows CLOCK_MONOTONIC; 0 ("no stamp") keeps this infallible.
            Err(_) => 0,
        }
    }
}

impl Clock for MonotonicClock {
    fn now_ns(&self) -> u64 {
        Self::read_ns()
    }
}

/// A clock advanced by hand: simulated time for in-process evaluation and tests. Clones share
/// the same time.
#[derive(Debug, Clone, Default)]
pub struct ManualClock {
    now_ns: Arc<AtomicU64>,
}

impl ManualClock {
    /// A clock that reads `now_ns` until moved.
    pub fn starting_at(now_ns: u64) -> Self {
        Self {
            now_ns: Arc::new(AtomicU64::new(now_ns)),
        }
    }

    /// Moves the time forward by `delta_ns`.
    pub fn advance_ns(&self, delta_ns: u64) {
        self.now_ns.fetch_add(delta_ns, Ordering::SeqCst);
    }

    /// Sets the time to `now_ns` (may go backward: tests only).
    pub fn set_ns(&self, now_ns: u64) {
        self.now_ns.store(now_ns, Ordering::SeqCst);
    }
}

impl Clock for ManualClock {
    fn now_ns(&self) -> u64 {
        self.now_ns.load(Ordering::SeqCst)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_clock_does_not_go_back() {
        let first = MonotonicClock.now_ns();
        let second = MonotonicClock.now_ns();
        assert!(second >= first);
        assert!(first > 0);
    }

    #[test]
    fn manual_clock_clones_share_time() {
        let clock = ManualClock::starting_at(5);
        let other = clock.clone();
        clock.advance_ns(10);
        assert_eq!(other.now_ns(), 15);
    }
}
