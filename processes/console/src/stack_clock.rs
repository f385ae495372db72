//! The stack's clock as the console reads it: `CLOCK_MONOTONIC` of the robot's computer, which
//! every stamp on the channels is on. On the robot that is this machine's own clock; a station's
//! console estimates the robot's from the stamps it receives (the smallest delay seen counts as
//! none, so ages shown there include the link's delay beyond that).

use std::sync::atomic::{AtomicI64, Ordering};

use harvest_ipc::MonotonicClock;

/// A stamp this much older than the estimate says is not a slow message but a clock that
/// started over, ns.
pub const RESTART_NS: i64 = 10_000_000_000;

/// This machine's monotonic clock plus an offset (module docs).
#[derive(Debug, Default)]
pub struct StackClock {
    offset_ns: AtomicI64,
    estimated: std::sync::atomic::AtomicBool,
}

impl StackClock {
    /// The stack's time now, ns.
    pub fn now_ns(&self) -> u64 {
        MonotonicClock::read_ns().saturating_add_signed(self.offset_ns.load(Ordering::Relaxed))
    }

    /// A message stamped `stamp_ns` on the stack clock arrived now: the offset becomes at
    /// least what this message implies (it cannot have arrived before it was stamped). One that
    /// implies an offset [`RESTART_NS`] or more below the estimate means the robot's clock
    /// started over (its computer restarted): the estimate starts over from it.
    pub fn observe(&self, stamp_ns: u64) {
        let local_ns = MonotonicClock::read_ns();
        let implied = i64::try_from(i128::from(stamp_ns) - i128::from(local_ns)).unwrap_or(0);
        let current = self.offset_ns.load(Ordering::Relaxed);
        let restarted = implied < current.saturating_sub(RESTART_NS);
        if !self.estimated.swap(true, Ordering::Relaxed) || restarted {
            self.offset_ns.store(implied, Ordering::Relaxed);
        } else {
            self.offset_ns.fetch_max(implied, Ordering::Relaxed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_local_clock_is_the_stack_clock_until_a_stamp_says_otherwise() {
        let clock = StackClock::default();
        let before = MonotonicClock::read_ns();
        assert!(clock.now_ns() >= before);
        // A robot whose clock is 1000 s ahead of this machine's.
        let robot_ns = before + 1_000_000_000_000;
        clock.observe(robot_ns);
        let now = clock.now_ns();
        assert!(
            now >= robot_ns && now < robot_ns + 1_000_000_000,
            "{now} vs {robot_ns}"
        );
        // A message that took longer does not move the estimate back.
        clock.observe(robot_ns - 5_000_000);
        assert!(clock.now_ns() >= now);
        // The robot's computer restarted: its clock counts from near zero again.
        clock.observe(1_000);
        assert!(clock.now_ns() < 1_000_000_000, "{}", clock.now_ns());
    }
}
