//! The simulated platform as a device: targets (or stop) go out on `hw/platform/command`, the
//! stages' positions come back on `hw/platform/feedback`, served by the simulator at the
//! controller's feedback rate (the way the real Arduino reports over serial).
//!
//! Whether the latest command has been acted on is known from the feedback's
//! `last_command_ns`, the stamp of the last command the device processed: until it reaches the
//! stamp of our latest command, [`Platform::position`] reports `in_motion`.

use super::{Platform, PlatformAxis, PlatformPosition, PlatformTravel};
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::{HW_PLATFORM_COMMAND, HW_PLATFORM_FEEDBACK};
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::PlatformCommand;
use harvest_ipc::payloads::PlatformFeedback;
use harvest_ipc::payloads::PlatformStatus;
use harvest_ipc::{Context, MonotonicClock, Publisher, Subscriber};
use std::time::Duration;

/// Errors of the simulated platform link.
#[derive(Debug, thiserror::Error)]
pub enum SimPlatformError {
    /// A target outside the stage's travel `[0, max_m]` or not finite; nothing was sent.
    #[error("{axis} target {value_m} m outside the travel [0, {max_m}] m or not finite")]
    OutOfTravel {
        /// The stage.
        axis: PlatformAxis,
        /// The target asked for, metres.
        value_m: f64,
        /// The stage's travel, metres.
        max_m: f64,
    },
    /// The device refused our latest target (its travel is narrower than the driver's).
    #[error("platform refused the target ({in_out_m} m in-out, {up_down_m} m up-down)")]
    DeviceRefused {
        /// The refused in-out target, metres.
        in_out_m: f64,
        /// The refused up-down target, metres.
        up_down_m: f64,
    },
    /// The device reports a stage fault (stall, limit switch).
    #[error("platform reports a stage fault at ({in_out_m} m in-out, {up_down_m} m up-down)")]
    DeviceFault {
        /// In-out stage position at the fault, metres.
        in_out_m: f64,
        /// Up-down stage position at the fault, metres.
        up_down_m: f64,
    },
    /// The feedback carries a status code this driver does not know.
    #[error("simulated platform: {0} in its feedback")]
    UnknownStatus(harvest_ipc::UnknownCode),
    /// No feedback newer than the timeout (is the sim process running?).
    #[error(
        "simulated platform sent no feedback within {timeout_ms} ms (is the sim process running?)"
    )]
    Silent {
        /// How long the driver waited, milliseconds.
        timeout_ms: u64,
    },
    /// The hardware channel failed.
    #[error("simulated platform link: {0}")]
    Link(#[from] IpcError),
}

impl DeviceError for SimPlatformError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::OutOfTravel { .. } | Self::DeviceRefused { .. } => ErrorKind::InvalidRequest,
            Self::DeviceFault { .. } | Self::UnknownStatus(_) => ErrorKind::Fault,
            Self::Silent { .. } => ErrorKind::Timeout,
            Self::Link(_) => ErrorKind::Disconnected,
        }
    }
}

/// Driver for the simulated platform.
pub struct SimPlatform {
    commands: Publisher<PlatformCommand>,
    feedback: Subscriber<PlatformFeedback>,
    travel: PlatformTravel,
    timeout: Duration,
    latest: Option<PlatformFeedback>,
    /// Stamp of our latest command (0: none sent).
    sent_ns: u64,
    /// Targets of our latest command, m `[in_out, up_down]`.
    sent_target_m: [f64; 2],
    /// Stamp of the command whose refusal was already reported.
    refusal_reported_ns: u64,
}

impl SimPlatform {
    /// Connects. `travel` is the travel the driver accepts (the installation's); `timeout`
    /// bounds the wait for the first feedback and how old the newest feedback may be.
    pub fn connect(
        context: &Context,
        travel: PlatformTravel,
        timeout: Duration,
    ) -> Result<Self, SimPlatformError> {
        let link =
            |error: harvest_ipc::error::OpenChannelError| SimPlatformError::Link(error.into());
        Ok(Self {
            commands: context.publisher(HW_PLATFORM_COMMAND).map_err(link)?,
            feedback: context.subscriber(HW_PLATFORM_FEEDBACK).map_err(link)?,
            travel,
            timeout,
            latest: None,
            sent_ns: 0,
            sent_target_m: [0.0; 2],
            refusal_reported_ns: 0,
        })
    }

    fn send(&mut self, stop: bool, target_m: [f64; 2]) -> Result<(), SimPlatformError> {
        // Strictly increasing, so the device's echo identifies this command.
        let stamp_ns = MonotonicClock::read_ns().max(self.sent_ns + 1);
        self.commands
            .publish_with(stamp_ns, |command| {
                command.target_in_out_m = target_m[0];
                command.target_up_down_m = target_m[1];
                command.stop = u8::from(stop);
                command._reserved = [0; 7];
            })
            .map_err(|error| SimPlatformError::Link(error.into()))?;
        self.sent_ns = stamp_ns;
        self.sent_target_m = target_m;
        tracing::debug!(stop, ?target_m, stamp_ns, "platform command sent");
        Ok(())
    }

    /// The newest feedback; waits (event-driven, bounded) for the first one, and refuses
    /// feedback older than the timeout.
    fn refresh(&mut self) -> Result<PlatformFeedback, SimPlatformError> {
        let receive = |feedback: &Subscriber<PlatformFeedback>| {
            feedback
                .receive_latest()
                .map(|sample| sample.map(|sample| *sample))
                .map_err(|error| SimPlatformError::Link(error.into()))
        };
        if let Some(sample) = receive(&self.feedback)? {
            self.latest = Some(sample);
        }
        if self.latest.is_none() {
            if let Err(error) = self.feedback.listener().timed_wait(|_| {}, self.timeout) {
                tracing::debug!(?error, "wait for platform feedback interrupted");
            }
            self.latest = receive(&self.feedback)?;
        }
        let silent = SimPlatformError::Silent {
            timeout_ms: self.timeout.as_millis() as u64,
        };
        let latest = self.latest.ok_or(silent)?;
        let age_ns = MonotonicClock::read_ns().saturating_sub(latest.header.capture_ns);
        if age_ns > self.timeout.as_nanos() as u64 {
            return Err(SimPlatformError::Silent {
                timeout_ms: self.timeout.as_millis() as u64,
            });
        }
        Ok(latest)
    }
}

impl Platform for SimPlatform {
    type Error = SimPlatformError;

    fn travel(&self) -> PlatformTravel {
        self.travel
    }

    fn move_to(&mut self, in_out_m: f64, up_down_m: f64) -> Result<(), Self::Error> {
        if let Some((axis, value_m)) = self.travel.first_violation([in_out_m, up_down_m]) {
            return Err(SimPlatformError::OutOfTravel {
                axis,
                value_m,
                max_m: self.travel.max_m(axis),
            });
        }
        self.send(false, [in_out_m, up_down_m])
    }

    fn stop(&mut self) -> Result<(), Self::Error> {
        let here_m = self
            .latest
            .map_or([0.0; 2], |feedback| [feedback.in_out_m, feedback.up_down_m]);
        self.send(true, here_m)
    }

    fn position(&mut self) -> Result<PlatformPosition, Self::Error> {
        let feedback = self.refresh()?;
        let acted_on = feedback.last_command_ns >= self.sent_ns;
        match feedback
            .status
            .get()
            .map_err(SimPlatformError::UnknownStatus)?
        {
            PlatformStatus::Fault => {
                return Err(SimPlatformError::DeviceFault {
                    in_out_m: feedback.in_out_m,
                    up_down_m: feedback.up_down_m,
                });
            }
            PlatformStatus::Refused
                if feedback.last_command_ns == self.sent_ns
                    && self.refusal_reported_ns != self.sent_ns =>
            {
                self.refusal_reported_ns = self.sent_ns;
                return Err(SimPlatformError::DeviceRefused {
                    in_out_m: self.sent_target_m[0],
                    up_down_m: self.sent_target_m[1],
                });
            }
            _ => {}
        }
        Ok(PlatformPosition {
            capture_ns: feedback.header.capture_ns,
            in_out_m: feedback.in_out_m,
            up_down_m: feedback.up_down_m,
            in_motion: feedback.in_motion != 0 || !acted_on,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::lost_link;

    #[test]
    fn every_error_maps_to_its_kind() {
        let out_of_travel = SimPlatformError::OutOfTravel {
            axis: PlatformAxis::InOut,
            value_m: 9.0,
            max_m: 0.5,
        };
        assert_eq!(out_of_travel.kind(), ErrorKind::InvalidRequest);
        let refused = SimPlatformError::DeviceRefused {
            in_out_m: 0.1,
            up_down_m: 0.2,
        };
        assert_eq!(refused.kind(), ErrorKind::InvalidRequest);
        let fault = SimPlatformError::DeviceFault {
            in_out_m: 0.1,
            up_down_m: 0.2,
        };
        assert_eq!(fault.kind(), ErrorKind::Fault);
        let unknown = SimPlatformError::UnknownStatus(harvest_ipc::UnknownCode {
            enum_name: "PlatformStatus",
            code: 200,
        });
        assert_eq!(unknown.kind(), ErrorKind::Fault);
        assert_eq!(
            SimPlatformError::Silent { timeout_ms: 500 }.kind(),
            ErrorKind::Timeout
        );
        assert_eq!(
            SimPlatformError::from(lost_link()).kind(),
            ErrorKind::Disconnected
        );
    }
}
