//! Why the link could not run.

use harvest_ipc::config_file::ConfigFileError;
use harvest_remote::SettingsError;

/// See the module docs.
#[derive(Debug, thiserror::Error)]
pub enum RemoteError {
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    #[error(transparent)]
    Settings(#[from] SettingsError),
    #[error(transparent)]
    ConfigFile(#[from] ConfigFileError),
    #[error("zenoh: {0}")]
    Zenoh(String),
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error(transparent)]
    Client(#[from] harvest_ipc::operator_client::OperatorClientError),
    #[error(transparent)]
    Token(#[from] harvest_operator::token::TokenError),
}

harvest_ipc::from_ipc_errors!(RemoteError);

impl From<zenoh::Error> for RemoteError {
    fn from(error: zenoh::Error) -> Self {
        Self::Zenoh(error.to_string())
    }
}
