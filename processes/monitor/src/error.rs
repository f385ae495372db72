//! Errors of `harvest monitor`.

use std::path::PathBuf;

/// Why the monitor could not run (violations are results, not errors).
#[derive(Debug, thiserror::Error)]
pub enum MonitorError {
    /// The recording could not be opened or read.
    #[error("recording {path}: {message}")]
    Recording {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// The stack's channels could not be opened.
    #[error("opening channels: {0}")]
    Channels(String),
    /// The wait set failed.
    #[error("wait set: {0}")]
    Wait(#[from] harvest_ipc::error::WaitError),
    /// A subscriber failed to receive.
    #[error("{0}")]
    Receive(#[from] harvest_ipc::error::ReceiveError),
    /// An argument is out of range.
    #[error("argument `{arg}` = {value}: {reason}")]
    InvalidArgument {
        /// The argument.
        arg: &'static str,
        /// Its value.
        value: String,
        /// What was expected.
        reason: &'static str,
    },
}
