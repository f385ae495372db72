//! [`ViolationOutlet`]: the live monitor's `safety/violation` publisher, which keeps asking for
//! the protective stop until the executive has engaged it.
//!
//! `safety/violation` keeps no history (a restarted executive must not stop the robot again for
//! a violation already released), so a stop request sent before the executive subscribed, or
//! while it restarts, would be lost. Until `safety/emergency_stop` is seen engaged, the outlet
//! sends the last stop-requesting violation again every [`STOP_RETRY`]. A request made while
//! the stop is seen engaged is not repeated: the stop it asks for is in effect (the executive
//! ignores stop requests while engaged, so a repeat would never be answered).

use std::time::{Duration, Instant};

use harvest_ipc::payloads::{SafetyViolation, ViolationAction, ViolationRule};
use harvest_ipc::{FixedString, MonotonicClock, Publisher};
use harvest_safety::safety_monitor::Violation;

use crate::error::MonitorError;
use crate::violation_message::fill_message;

/// How often an unanswered stop request is sent again.
pub const STOP_RETRY: Duration = Duration::from_millis(100);

/// The publisher, the action it attaches, and the stop request not yet answered.
pub struct ViolationOutlet {
    publisher: Publisher<SafetyViolation>,
    action: Option<ViolationAction>,
    published: u64,
    pending_stop: Option<(SafetyViolation, Instant)>,
    /// The last `safety/emergency_stop` message seen was engaged.
    stop_in_effect: bool,
}

impl ViolationOutlet {
    /// An outlet publishing with `action` (`None`: only the reaction measurement's request).
    pub fn new(publisher: Publisher<SafetyViolation>, action: Option<ViolationAction>) -> Self {
        Self {
            publisher,
            action,
            published: 0,
            pending_stop: None,
            stop_in_effect: false,
        }
    }

    /// Messages published so far.
    pub fn published(&self) -> u64 {
        self.published
    }

    /// Publishes `violation` with the outlet's action (nothing without one).
    pub fn violation(&mut self, violation: &Violation) -> Result<(), MonitorError> {
        let Some(action) = self.action else {
            return Ok(());
        };
        let mut message = SafetyViolation::default();
        fill_message(&mut message, violation, action);
        tracing::warn!(%violation, ?action, "safety violation published");
        self.send(message)
    }

    /// Asks for the stop with no rule broken (`--engage-stop-after`).
    pub fn measurement_stop(&mut self) -> Result<(), MonitorError> {
        let message = SafetyViolation {
            violated_ns: MonotonicClock::read_ns(),
            rule: ViolationRule::ReactionMeasurement.into(),
            action: ViolationAction::Stop.into(),
            description: FixedString::new(
                "harvest monitor: stop requested to measure the reaction",
            ),
            ..SafetyViolation::default()
        };
        tracing::warn!("protective stop requested by the monitor (reaction measurement)");
        self.send(message)
    }

    /// A `safety/emergency_stop` message: engaged answers the pending request; released
    /// means the next request must be repeated until answered.
    pub fn stop_seen(&mut self, engaged: bool) {
        self.stop_in_effect = engaged;
        if engaged {
            self.pending_stop = None;
        }
    }

    /// Sends the pending stop request again when [`STOP_RETRY`] has passed.
    pub fn retry(&mut self) -> Result<(), MonitorError> {
        match self.pending_stop {
            Some((message, at)) if at.elapsed() >= STOP_RETRY => {
                tracing::debug!("stop request not answered yet: sent again");
                self.send(message)
            }
            _ => Ok(()),
        }
    }

    fn send(&mut self, message: SafetyViolation) -> Result<(), MonitorError> {
        self.publisher
            .publish_with(MonotonicClock::read_ns(), |out| *out = message)
            .map_err(|error| MonitorError::Channels(error.to_string()))?;
        self.published += 1;
        if message.requests_stop() && !self.stop_in_effect {
            self.pending_stop = Some((message, Instant::now()));
        }
        Ok(())
    }
}
