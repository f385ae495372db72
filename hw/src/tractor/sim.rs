//! The simulated tractor as a device: targets (or stop) go out on `hw/tractor/command`, the
//! trailer's position comes back on `hw/tractor/feedback`, served by the simulator.
//!
//! An advance is sent as an absolute target (the latest position plus the distance), so a
//! command read twice does not drive twice. Whether the latest command has been acted on is
//! known from the feedback's `last_command_ns`.

use super::{Tractor, TractorPosition};
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::{HW_TRACTOR_COMMAND, HW_TRACTOR_FEEDBACK};
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::TractorStatus;
use harvest_ipc::payloads::{TractorCommand, TractorFeedback};
use harvest_ipc::{Context, MonotonicClock, Publisher, Subscriber};
use std::time::Duration;

/// Errors of the simulated tractor link.
#[derive(Debug, thiserror::Error)]
pub enum SimTractorError {
    /// A distance that is negative or not finite, or a target past the end of the row.
    #[error(
        "advance of {distance_m} m from {position_m} m refused: must be finite, >= 0 and end \
         before the end of the row at {row_end_m} m"
    )]
    InvalidAdvance {
        /// The advance asked for, metres.
        distance_m: f64,
        /// The trailer's position, metres along the row.
        position_m: f64,
        /// The end of the row, metres along the row.
        row_end_m: f64,
    },
    /// The device refused our latest target.
    #[error("tractor refused the target {target_m} m")]
    DeviceRefused {
        /// The refused target, metres along the row.
        target_m: f64,
    },
    /// The feedback carries a status code this driver does not know.
    #[error("simulated tractor: {0} in its feedback")]
    UnknownStatus(harvest_ipc::UnknownCode),
    /// No feedback newer than the timeout (is the sim process running?).
    #[error(
        "simulated tractor sent no feedback within {timeout_ms} ms (is the sim process running?)"
    )]
    Silent {
        /// How long the driver waited, milliseconds.
        timeout_ms: u64,
    },
    /// The hardware channel failed.
    #[error("simulated tractor link: {0}")]
    Link(#[from] IpcError),
}

impl DeviceError for SimTractorError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::InvalidAdvance { .. } | Self::DeviceRefused { .. } => ErrorKind::InvalidRequest,
            Self::UnknownStatus(_) => ErrorKind::Fault,
            Self::Silent { .. } => ErrorKind::Timeout,
            Self::Link(_) => ErrorKind::Disconnected,
        }
    }
}

/// Driver for the simulated tractor.
pub struct SimTractor {
    commands: Publisher<TractorCommand>,
    feedback: Subscriber<TractorFeedback>,
    timeout: Duration,
    latest: Option<TractorFeedback>,
    sent_ns: u64,
    sent_target_m: f64,
    refusal_reported_ns: u64,
}

impl SimTractor {
    /// Connects; `timeout` bounds the wait for the first feedback and its age.
    pub fn connect(context: &Context, timeout: Duration) -> Result<Self, SimTractorError> {
        let link =
            |error: harvest_ipc::error::OpenChannelError| SimTractorError::Link(error.into());
        Ok(Self {
            commands: context.publisher(HW_TRACTOR_COMMAND).map_err(link)?,
            feedback: context.subscriber(HW_TRACTOR_FEEDBACK).map_err(link)?,
            timeout,
            latest: None,
            sent_ns: 0,
            sent_target_m: 0.0,
            refusal_reported_ns: 0,
        })
    }

    fn send(&mut self, stop: bool, target_m: f64) -> Result<(), SimTractorError> {
        let stamp_ns = MonotonicClock::read_ns().max(self.sent_ns + 1);
        self.commands
            .publish_with(stamp_ns, |command| {
                command.target_m = target_m;
                command.stop = u8::from(stop);
                command._reserved = [0; 7];
            })
            .map_err(|error| SimTractorError::Link(error.into()))?;
        self.sent_ns = stamp_ns;
        self.sent_target_m = target_m;
        tracing::debug!(stop, target_m, stamp_ns, "tractor command sent");
        Ok(())
    }

    fn refresh(&mut self) -> Result<TractorFeedback, SimTractorError> {
        let receive = |feedback: &Subscriber<TractorFeedback>| {
            feedback
                .receive_latest()
                .map(|sample| sample.map(|sample| *sample))
                .map_err(|error| SimTractorError::Link(error.into()))
        };
        if let Some(sample) = receive(&self.feedback)? {
            self.latest = Some(sample);
        }
        if self.latest.is_none() {
            if let Err(error) = self.feedback.listener().timed_wait(|_| {}, self.timeout) {
                tracing::debug!(?error, "wait for tractor feedback interrupted");
            }
            self.latest = receive(&self.feedback)?;
        }
        let silent = SimTractorError::Silent {
            timeout_ms: self.timeout.as_millis() as u64,
        };
        let latest = self.latest.ok_or(silent)?;
        let age_ns = MonotonicClock::read_ns().saturating_sub(latest.header.capture_ns);
        if age_ns > self.timeout.as_nanos() as u64 {
            return Err(SimTractorError::Silent {
                timeout_ms: self.timeout.as_millis() as u64,
            });
        }
        Ok(latest)
    }
}

impl Tractor for SimTractor {
    type Error = SimTractorError;

    fn advance(&mut self, distance_m: f64) -> Result<(), Self::Error> {
        let feedback = self.refresh()?;
        // From the target it drives to (an advance while moving adds to the previous one).
        let from_m = if feedback.last_command_ns >= self.sent_ns {
            feedback.target_m
        } else {
            self.sent_target_m
        };
        let target_m = from_m + distance_m;
        if !(distance_m.is_finite() && distance_m >= 0.0 && target_m <= feedback.row_end_m) {
            return Err(SimTractorError::InvalidAdvance {
                distance_m,
                position_m: from_m,
                row_end_m: feedback.row_end_m,
            });
        }
        self.send(false, target_m)
    }

    fn stop(&mut self) -> Result<(), Self::Error> {
        let here_m = self.latest.map_or(0.0, |feedback| feedback.position_m);
        self.send(true, here_m)
    }

    fn position(&mut self) -> Result<TractorPosition, Self::Error> {
        let feedback = self.refresh()?;
        let status = feedback
            .status
            .get()
            .map_err(SimTractorError::UnknownStatus)?;
        if status == TractorStatus::Refused
            && feedback.last_command_ns == self.sent_ns
            && self.refusal_reported_ns != self.sent_ns
        {
            self.refusal_reported_ns = self.sent_ns;
            return Err(SimTractorError::DeviceRefused {
                target_m: self.sent_target_m,
            });
        }
        Ok(TractorPosition {
            capture_ns: feedback.header.capture_ns,
            position_m: feedback.position_m,
            row_end_m: feedback.row_end_m,
            in_motion: feedback.in_motion != 0 || feedback.last_command_ns < self.sent_ns,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::lost_link;

    #[test]
    fn every_error_maps_to_its_kind() {
        let invalid = SimTractorError::InvalidAdvance {
            distance_m: -1.0,
            position_m: 2.0,
            row_end_m: 10.0,
        };
        assert_eq!(invalid.kind(), ErrorKind::InvalidRequest);
        let refused = SimTractorError::DeviceRefused { target_m: 12.0 };
        assert_eq!(refused.kind(), ErrorKind::InvalidRequest);
        let unknown = SimTractorError::UnknownStatus(harvest_ipc::UnknownCode {
            enum_name: "TractorStatus",
            code: 200,
        });
        assert_eq!(unknown.kind(), ErrorKind::Fault);
        assert_eq!(
            SimTractorError::Silent { timeout_ms: 500 }.kind(),
            ErrorKind::Timeout
        );
        assert_eq!(
            SimTractorError::from(lost_link()).kind(),
            ErrorKind::Disconnected
        );
    }
}
