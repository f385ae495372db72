//! Why `harvest eval perception` could not run.

use std::path::PathBuf;

use harvest_perception::pipeline::PerceptionSetupError;
use harvest_sim::{OrchardError, RenderError, ScenarioError};

/// Failure of [`crate::perception::run_eval_perception`].
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A command-line value is unusable.
    #[error("{argument} = {value}: {reason}")]
    BadArgument {
        argument: &'static str,
        value: String,
        reason: &'static str,
    },
    /// The scenario preset or file could not be loaded.
    #[error("scenario `{scenario}`: {source}")]
    Scenario {
        scenario: String,
        source: Box<ScenarioError>,
    },
    /// The world of one frame could not be generated.
    #[error("scenario `{scenario}`, seed {seed}: cannot generate the world: {source}")]
    World {
        scenario: String,
        seed: u64,
        source: Box<OrchardError>,
    },
    /// The simulator could not render a frame.
    #[error("scenario `{scenario}`: cannot render: {source}")]
    Render {
        scenario: String,
        source: Box<RenderError>,
    },
    /// The perception node refused the frame's camera parameters.
    #[error("scenario `{scenario}`, estimator {estimator}: perception setup failed: {source}")]
    PerceptionSetup {
        scenario: String,
        estimator: &'static str,
        source: Box<PerceptionSetupError>,
    },
    /// `--detector` / `--model` do not fit together, or the detector cannot start.
    #[error("detector: {0}")]
    Detector(String),
    /// The simulated LiDAR could not be set up.
    #[error("simulated LiDAR: {source}")]
    Lidar {
        source: Box<harvest_sim::lidar_device::LidarDeviceError>,
    },
    /// A LiDAR window could not be fused into the frame's depth geometry.
    #[error("LiDAR fusion: {source}")]
    Fusion {
        source: Box<harvest_lidar::FusionError>,
    },
    /// The Table-III repeatability comparison failed.
    #[error("Table III comparison: {source}")]
    TableIii {
        source: Box<crate::lidar::evaluation::EvalLidarError>,
    },
    /// The thread CPU clock could not be read.
    #[error("cannot read the thread CPU clock: {0}")]
    CpuClock(nix::Error),
    /// The report could not be encoded as JSON.
    #[error("cannot encode the report as JSON: {0}")]
    Encode(#[from] serde_json::Error),
    /// The JSON report could not be written.
    #[error("cannot write the JSON report to {path}: {source}")]
    WriteJson {
        path: PathBuf,
        source: std::io::Error,
    },
}
