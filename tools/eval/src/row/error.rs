//! Errors of `harvest eval row`.

use std::path::PathBuf;

use harvest_field::StopCycleError;
use harvest_sim::OrchardError;
use harvest_sim::platform_device::PlatformDeviceError;
use harvest_sim::row::RowError;

use crate::harvest::HarvestEvalError;

/// Why a row evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum RowEvalError {
    /// The row scenario could not be loaded (file, line and key named by the row reader).
    #[error("row `{row}`")]
    Row {
        /// The `--rows` value.
        row: String,
        source: Box<RowError>,
    },
    /// The row's world could not be generated.
    #[error("row `{row}` seed {seed}")]
    World {
        row: String,
        seed: u64,
        source: Box<OrchardError>,
    },
    /// The harvesting episode (nodes, devices, safety trace) failed.
    #[error(transparent)]
    Harvest(#[from] HarvestEvalError),
    /// The stop cycle refused the row's stops or spacing.
    #[error("stop cycle: {0}")]
    StopCycle(#[from] StopCycleError),
    /// The simulated platform refused its configuration.
    #[error("platform: {0}")]
    Platform(#[from] PlatformDeviceError),
    /// The stop cycle asked for a platform or tractor move the device refused.
    #[error("{device} refused {what} at {t_s:.3} s")]
    Refused {
        device: &'static str,
        what: String,
        t_s: f64,
    },
    /// An argument is out of range.
    #[error("argument `{arg}` = {value}: {reason}")]
    InvalidArgument {
        arg: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The JSON report could not be written.
    #[error("writing {path}: {message}")]
    Write { path: PathBuf, message: String },
}
