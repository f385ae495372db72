//! Why the console stopped.

/// The console's errors.
#[derive(Debug, thiserror::Error)]
pub enum ConsoleError {
    /// A thread could not be started or ended badly.
    #[error("console: {0}")]
    Thread(String),
    /// The operator channels' client failed.
    #[error(transparent)]
    Client(#[from] harvest_ipc::operator_client::OperatorClientError),
    /// The transport failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(ConsoleError);
