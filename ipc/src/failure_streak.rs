//! Device exchanges that fail in a row in a periodic control loop.
//!
//! The arm and vacuum processes read their device once per tick. One failed read is tolerated
//! (the tick goes on without fresh readings and the process reports itself degraded); a streak
//! of them as long as the process's limit ends it, so that the supervisor restarts it. Only the
//! first failure of a streak is logged, so a device that stays unreachable does not flood the
//! log at 200 Hz.

use crate::payloads::ProcessRunState;

/// Counts failed device exchanges: the current streak and the total since start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FailureStreak {
    limit: u32,
    in_a_row: u32,
    total: u64,
}

impl FailureStreak {
    /// A streak that gives up after `limit` failures in a row.
    pub fn new(limit: u32) -> Self {
        Self {
            limit,
            in_a_row: 0,
            total: 0,
        }
    }

    /// An exchange succeeded: the streak ends.
    pub fn succeeded(&mut self) {
        self.in_a_row = 0;
    }

    /// An exchange failed with `error` (what failed: `what`, e.g. "encoder read"). The first
    /// failure of a streak is logged at WARN. Returns the length of the streak once it reached
    /// the limit (the caller stops), `None` while it is tolerated.
    pub fn failed(&mut self, what: &str, error: &dyn std::fmt::Display) -> Option<u32> {
        self.in_a_row = self.in_a_row.saturating_add(1);
        self.total = self.total.saturating_add(1);
        if self.in_a_row == 1 {
            tracing::warn!(%error, "{what} failed");
        }
        (self.in_a_row >= self.limit).then_some(self.in_a_row)
    }

    /// What the heartbeat says: degraded while the last exchange failed.
    pub fn run_state(&self) -> ProcessRunState {
        if self.in_a_row > 0 {
            ProcessRunState::Degraded
        } else {
            ProcessRunState::Running
        }
    }

    /// Failed exchanges since start.
    pub fn total(&self) -> u64 {
        self.total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gives_up_at_the_limit_of_failures_in_a_row() {
        let mut streak = FailureStreak::new(3);
        assert_eq!(streak.run_state(), ProcessRunState::Running);
        assert_eq!(streak.failed("read", &"timeout"), None);
        assert_eq!(streak.failed("read", &"timeout"), None);
        assert_eq!(streak.run_state(), ProcessRunState::Degraded);
        // A success ends the streak: two more failures are tolerated again.
        streak.succeeded();
        assert_eq!(streak.run_state(), ProcessRunState::Running);
        assert_eq!(streak.failed("read", &"timeout"), None);
        assert_eq!(streak.failed("read", &"timeout"), None);
        assert_eq!(streak.failed("read", &"timeout"), Some(3));
        assert_eq!(streak.failed("read", &"timeout"), Some(4));
        assert_eq!(streak.total(), 6);
    }
}
