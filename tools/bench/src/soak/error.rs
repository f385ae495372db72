//! Why `harvest soak` could not run to its report.

use std::path::PathBuf;
use std::process::ExitStatus;

#[derive(Debug, thiserror::Error)]
pub enum SoakError {
    /// An option value is out of range.
    #[error("--{option} {value}: {reason}")]
    InvalidOption {
        option: &'static str,
        value: String,
        reason: String,
    },
    /// The embedded default launch file no longer has what the soak rewrites in its copy.
    #[error("the default launch file changed: {what} (processes/supervisor/launch/default.toml)")]
    LaunchChanged { what: String },
    /// The rewritten launch file does not parse.
    #[error(transparent)]
    Launch(#[from] harvest_supervisor::LaunchError),
    /// A file of the run could not be written or read.
    #[error("{path}: {source}")]
    File {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// `harvest up` (or `harvest ctl`) could not be started.
    #[error("cannot start {exe}: {source}")]
    Spawn {
        exe: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The stack did not come up (no control token file) in time.
    #[error("the stack did not start within {waited_s} s (log {log}):\n{tail}")]
    StackNotStarted {
        waited_s: u64,
        log: PathBuf,
        tail: String,
    },
    /// `harvest up` ended before the soak's end.
    #[error("`harvest up` ended early ({status}) after {after_s:.0} s (log {log}):\n{tail}")]
    StackEnded {
        status: ExitStatus,
        after_s: f64,
        log: PathBuf,
        tail: String,
    },
    /// The soak's own node or channels in the domain failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// Writing the JSON report failed.
    #[error("encoding the report: {0}")]
    Json(#[from] serde_json::Error),
}

harvest_ipc::from_ipc_errors!(SoakError);
