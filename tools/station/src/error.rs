//! The station's errors.

/// Why the station's console cannot run.
#[derive(Debug, thiserror::Error)]
pub enum StationError {
    #[error(transparent)]
    Link(#[from] harvest_remote_process::RemoteError),
    #[error(transparent)]
    Console(#[from] harvest_console::ConsoleError),
    #[error("zenoh: {0}")]
    Zenoh(String),
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

impl From<zenoh::Error> for StationError {
    fn from(error: zenoh::Error) -> Self {
        Self::Zenoh(error.to_string())
    }
}
harvest_ipc::from_ipc_errors!(StationError);
