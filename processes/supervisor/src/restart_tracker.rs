//! The restart decision for one process: policy, budget within a window, exponential backoff.
//! Pure logic over instants handed in, so it is tested without processes or sleeping.

use crate::launch::{ProcessSpec, RestartPolicy};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// What to do after a process exited.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RestartDecision {
    /// Start it again at this instant.
    RestartAt(Instant),
    /// It exited successfully and the policy does not restart it.
    Finished,
    /// Its restart budget is spent (or the policy is `never` after a failure).
    FailedForGood,
}

#[derive(Debug, Clone)]
pub struct RestartTracker {
    policy: RestartPolicy,
    max_restarts: u32,
    window: Duration,
    backoff_initial: Duration,
    backoff_max: Duration,
    restarts_in_window: VecDeque<Instant>,
    consecutive: u32,
    total: u32,
}

impl RestartTracker {
    pub fn new(spec: &ProcessSpec) -> Self {
        Self {
            policy: spec.restart,
            max_restarts: spec.max_restarts,
            window: spec.restart_window,
            backoff_initial: spec.backoff_initial,
            backoff_max: spec.backoff_max,
            restarts_in_window: VecDeque::new(),
            consecutive: 0,
            total: 0,
        }
    }

    /// Total restarts so far.
    pub fn restarts(&self) -> u32 {
        self.total
    }

    /// The process ran healthily for a while: later failures back off from the start again.
    pub fn mark_stable(&mut self) {
        self.consecutive = 0;
    }

    /// Decides after an exit at `now`. `failed` is false only for a clean exit (status 0).
    pub fn on_exit(&mut self, now: Instant, failed: bool) -> RestartDecision {
        let wants_restart = match self.policy {
            RestartPolicy::Never => false,
            RestartPolicy::OnFailure => failed,
            RestartPolicy::Always => true,
        };
        if !wants_restart {
            return if failed {
                RestartDecision::FailedForGood
            } else {
                RestartDecision::Finished
            };
        }
        while let Some(&oldest) = self.restarts_in_window.front() {
            if now.duration_since(oldest) > self.window {
                self.restarts_in_window.pop_front();
            } else {
                break;
            }
        }
        if self.restarts_in_window.len() as u32 >= self.max_restarts {
            return RestartDecision::FailedForGood;
        }
        let factor = 1u32 << self.consecutive.min(16);
        let backoff = self
            .backoff_initial
            .saturating_mul(factor)
            .min(self.backoff_max);
        self.consecutive += 1;
        self.total += 1;
        self.restarts_in_window.push_back(now);
        RestartDecision::RestartAt(now + backoff)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(restart: RestartPolicy, max_restarts: u32) -> ProcessSpec {
        ProcessSpec {
            name: "p".into(),
            command: "camera".into(),
            executable: None,
            args: vec![],
            restart,
            max_restarts,
            restart_window: Duration::from_secs(10),
            backoff_initial: Duration::from_millis(100),
            backoff_max: Duration::from_millis(350),
            scheduling: Default::default(),
            critical: true,
        }
    }

    #[test]
    fn on_failure_backs_off_then_gives_up() {
        let mut tracker = RestartTracker::new(&spec(RestartPolicy::OnFailure, 3));
        let t0 = Instant::now();
        assert_eq!(
            tracker.on_exit(t0, true),
            RestartDecision::RestartAt(t0 + Duration::from_millis(100))
        );
        assert_eq!(
            tracker.on_exit(t0, true),
            RestartDecision::RestartAt(t0 + Duration::from_millis(200))
        );
        assert_eq!(
            tracker.on_exit(t0, true),
            RestartDecision::RestartAt(t0 + Duration::from_millis(350))
        );
        assert_eq!(tracker.on_exit(t0, true), RestartDecision::FailedForGood);
        assert_eq!(tracker.restarts(), 3);
    }

    #[test]
    fn window_forgets_old_restarts() {
        let mut tracker = RestartTracker::new(&spec(RestartPolicy::OnFailure, 1));
        let t0 = Instant::now();
        assert!(matches!(
            tracker.on_exit(t0, true),
            RestartDecision::RestartAt(_)
        ));
        assert_eq!(
            tracker.on_exit(t0 + Duration::from_secs(5), true),
            RestartDecision::FailedForGood
        );
        assert!(matches!(
            tracker.on_exit(t0 + Duration::from_secs(11), true),
            RestartDecision::RestartAt(_)
        ));
    }

    #[test]
    fn clean_exit_and_never() {
        let mut on_failure = RestartTracker::new(&spec(RestartPolicy::OnFailure, 3));
        assert_eq!(
            on_failure.on_exit(Instant::now(), false),
            RestartDecision::Finished
        );
        let mut never = RestartTracker::new(&spec(RestartPolicy::Never, 3));
        assert_eq!(
            never.on_exit(Instant::now(), true),
            RestartDecision::FailedForGood
        );
        let mut always = RestartTracker::new(&spec(RestartPolicy::Always, 3));
        assert!(matches!(
            always.on_exit(Instant::now(), false),
            RestartDecision::RestartAt(_)
        ));
    }
}
