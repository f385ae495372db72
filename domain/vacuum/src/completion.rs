//! When the harvest of what the camera sees is complete ([`CompletionWatch`]): nothing
//! assigned, dispatched or running, every taking-part arm idle, and the detection sets since
//! the last attempt brought nothing new to pick, for a settled time. The vacuum supervisor
//! publishes `HarvestComplete` on it; it lives beside [`crate::node::VacuumNode`] so that
//! every runner of the node (the process, an evaluation) decides completion by the same rule.

use crate::node::VacuumNodeEvent;

/// Nothing left to do for this long means the harvest is complete, ms: the vacuum process's
/// default (`complete_after_ms`).
pub const DEFAULT_COMPLETE_AFTER_MS: u64 = 2000;

/// Tracks whether the harvest of what the camera sees is complete (module documentation).
#[derive(Debug, Clone, Copy, Default)]
pub struct CompletionWatch {
    /// Detection sets processed since the last attempt ended (or since the start).
    sets_since_attempt: u32,
    /// When the idle condition started to hold, ns.
    idle_since_ns: Option<u64>,
    /// `HarvestComplete` was published and nothing was assigned since.
    reported: bool,
}

impl CompletionWatch {
    pub fn on_event(&mut self, event: &VacuumNodeEvent) {
        match event {
            VacuumNodeEvent::Replanned { .. } => {
                self.sets_since_attempt = self.sets_since_attempt.saturating_add(1);
            }
            VacuumNodeEvent::AttemptFinished { .. } | VacuumNodeEvent::DispatchTimedOut { .. } => {
                self.sets_since_attempt = 0;
            }
            VacuumNodeEvent::TargetDispatched { .. } => {
                self.sets_since_attempt = 0;
                self.reported = false;
            }
            _ => {}
        }
    }

    /// True on the tick the harvest becomes complete.
    pub fn update(&mut self, now_ns: u64, idle: bool, after_ns: u64) -> bool {
        if !idle || self.sets_since_attempt == 0 {
            self.idle_since_ns = None;
            return false;
        }
        let since = *self.idle_since_ns.get_or_insert(now_ns);
        if !self.reported && now_ns.saturating_sub(since) >= after_ns {
            self.reported = true;
            return true;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn completion_needs_a_fresh_detection_set_and_the_idle_time() {
        let mut watch = CompletionWatch::default();
        let ms = 1_000_000;
        // Idle from the start but no detection set yet: not complete.
        assert!(!watch.update(0, true, 100 * ms));
        assert!(!watch.update(200 * ms, true, 100 * ms));
        let replanned = VacuumNodeEvent::Replanned {
            summary: crate::replan::ReplanSummary::default(),
            queued: [0, 0],
            invalid: 0,
            given_up: 0,
        };
        watch.on_event(&replanned);
        assert!(!watch.update(300 * ms, true, 100 * ms));
        assert!(!watch.update(350 * ms, false, 100 * ms));
        assert!(!watch.update(360 * ms, true, 100 * ms));
        assert!(watch.update(460 * ms, true, 100 * ms));
        // Reported once.
        assert!(!watch.update(600 * ms, true, 100 * ms));
    }
}
