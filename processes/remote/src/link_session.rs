//! Opening the Zenoh session of either side from the link's settings: the settings file (or
//! the side's default), the endpoints given on the command line added, the security rules
//! checked (`harvest_remote::link_settings`), the password read from its private file, and
//! Zenoh configured from the JSON those settings become, nothing else.

use std::path::PathBuf;

use harvest_ipc::config_file::read_toml;
use harvest_remote::{LinkPriority, LinkSettings};
use zenoh::Wait;
use zenoh::qos::Priority;

use crate::error::RemoteError;

/// The link options both sides share on the command line.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct LinkArgs {
    /// The link's settings (TOML: listen/connect endpoints, [tls], [auth], [access]; see
    /// docs/operating.md).
    #[arg(long = "link", value_name = "FILE", global = true)]
    pub link_file: Option<PathBuf>,
    /// An endpoint to listen on, added to the file's (`tcp/127.0.0.1:7447`).
    #[arg(long = "listen", value_name = "ENDPOINT", global = true)]
    pub listen: Vec<String>,
    /// An endpoint to connect to, added to the file's (`tcp/127.0.0.1:7447`).
    #[arg(long = "connect", value_name = "ENDPOINT", global = true)]
    pub connect: Vec<String>,
}

impl LinkArgs {
    /// The settings: the file, else `default`; the command line's endpoints added.
    pub fn settings(&self, default: LinkSettings) -> Result<LinkSettings, RemoteError> {
        let mut settings = match &self.link_file {
            Some(path) => read_toml::<LinkSettings>(path, "link settings")?,
            None => default,
        };
        settings.listen.extend(self.listen.iter().cloned());
        settings.connect.extend(self.connect.iter().cloned());
        settings.check()?;
        Ok(settings)
    }
}

/// Opens a session; `key_root` is what the access rules of a listener cover.
pub fn open_session(
    settings: &LinkSettings,
    key_root: &str,
) -> Result<zenoh::Session, RemoteError> {
    let password = settings.read_password()?;
    let json = settings.zenoh_config(password.as_deref(), key_root)?;
    let config = zenoh::Config::from_json5(&json.to_string())?;
    Ok(zenoh::open(config).wait()?)
}

/// Zenoh's priority for the link's.
pub fn priority(priority: LinkPriority) -> Priority {
    match priority {
        LinkPriority::RealTime => Priority::RealTime,
        LinkPriority::InteractiveHigh => Priority::InteractiveHigh,
        LinkPriority::Data => Priority::Data,
        LinkPriority::DataLow => Priority::DataLow,
        LinkPriority::Background => Priority::Background,
    }
}
