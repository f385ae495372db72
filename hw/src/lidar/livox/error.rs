//! Errors of the Livox driver, mapped to the shared [`ErrorKind`].

use crate::error_kind::{DeviceError, ErrorKind};
use std::time::Duration;

/// What went wrong with the Livox device or its link.
#[derive(Debug, thiserror::Error)]
pub enum LivoxError {
    /// A socket could not be opened, bound or configured (port in use, no such address).
    #[error("livox socket {what}: {source}")]
    Socket {
        /// What was being done (`bind data port`, ...).
        what: &'static str,
        /// The system's error.
        source: std::io::Error,
    },
    /// Sending or receiving on an open socket failed.
    #[error("livox link {what}: {source}")]
    Link {
        /// What was being done (`send heartbeat`, ...).
        what: &'static str,
        /// The system's error.
        source: std::io::Error,
    },
    /// Nothing (no point packet, no acknowledgement) came from the device for `silent_for`;
    /// the driver keeps trying to reconnect.
    #[error("livox device {device} silent for {silent_for:?}; reconnecting")]
    Silent {
        /// The device (broadcast code or address).
        device: String,
        /// How long nothing came.
        silent_for: Duration,
    },
    /// The configuration cannot work (the message names the option and its value).
    #[error("livox configuration: {0}")]
    Config(String),
}

impl DeviceError for LivoxError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Socket { .. } | Self::Link { .. } | Self::Silent { .. } => {
                ErrorKind::Disconnected
            }
            Self::Config(_) => ErrorKind::InvalidRequest,
        }
    }
}
