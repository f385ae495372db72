//! `harvest perception`: `camera/rgbd` -> `perception/apples`.
//!
//! [`PerceptionTask`] (`harvest_perception::task`: the per-frame work, the newest frame only,
//! read and written in place) on the runtime, woken by each frame's event on `camera/rgbd`
//! ([`Wake::Input`]). This file wires the arguments into it.
//!
//! Detector (`[detector]` in the config, or `--detector` / `--model`): built before the process
//! joins the channels, so a model that cannot be loaded, or fits no known layout, stops the
//! process at start with the reason.
//!
//! Laser refinement (`[laser]` in the config): with `--laser-calibration FILE` (the ALACS
//! unit's calibration) only apples in the laser's reach are asked for
//! ([`harvest_laser::reach::LaserReach`], the same check the laser process makes).
//!
//! Depth source (`depth_source` in the config, or `--depth-source`): with `lidar_fused` the
//! process also reads `lidar/points` and localizes from the fused depth image ([`FusedDepth`]).
//! The extrinsic is `--lidar-extrinsic FILE` (written by `harvest calibrate lidar-camera
//! --output`); it is required, as the camera calibration is.
//!
//! Colour-only frames (a GigE Vision camera, no depth of its own) need the fused source: before
//! the first cloud has been fused they are refused (warned once, the heartbeat degraded); with
//! the ToF source the process stops at the first such frame, naming the fix
//! ([`harvest_perception::task::PerceptionTaskError`]).
//!
//! The heartbeat's figure is the age of the last frame worked on (`frame_age_ns`); the frames
//! skipped and the largest age are logged when the process stops.

use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, alacs_camera_intrinsics};
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::{Context, Domain};
use harvest_laser::calibration::read_extrinsics;
use harvest_laser::{LaserReach, ScanConfig};
use harvest_lidar::ExtrinsicFile;
use harvest_perception::calibration::Calibration;
use harvest_perception::config_file::{ConfigFileError, read_config};
use harvest_perception::depth_source::{DepthSource, FusedDepth};
use harvest_perception::detector::{Detector, DetectorKind, make_detector};
use harvest_perception::estimator::EstimatorKind;
use harvest_perception::node::PerceptionNode;
use harvest_perception::pipeline::PerceptionConfig;
use harvest_perception::task::PerceptionTask;
use harvest_runtime::{RunError, Wake, WakeOptions, run_on_wake};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

#[derive(Debug, Clone, clap::Args)]
pub struct PerceptionArgs {
    /// Camera calibration (TOML: `[camera.robot_from_camera]`), required: where the camera sits
    /// on this robot. The simulated robot's is `sim/camera_calibration.toml`.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Perception configuration (TOML, every key optional; see
    /// domain/perception/config/default.toml); default: the built-in values.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Localization estimator (overrides the config's `estimator.kind`; default there:
    /// sphere fit).
    #[arg(long)]
    pub estimator: Option<EstimatorKind>,
    /// Detector: `color-segmentation` or `onnx` (overrides the config's `[detector] kind`;
    /// default there: colour segmentation).
    #[arg(long)]
    pub detector: Option<DetectorKind>,
    /// The ONNX model of the `onnx` detector (a YOLOv8/YOLO11 detect or segment export;
    /// overrides the config's `[detector] model`). Other `[detector]` keys (classes, thresholds,
    /// providers) come from the config.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Ask the laser scanner for no scans (overrides the config's `laser.enabled`).
    #[arg(long)]
    pub no_laser: bool,
    /// ALACS calibration file (the laser process's `--calibration`, e.g.
    /// `sim/alacs_calibration.toml`): with it only apples in the laser's reach are asked for
    /// (the check the laser makes before it scans); without it every apple the scan policy
    /// picks is asked for.
    #[arg(long)]
    pub laser_calibration: Option<PathBuf>,
    /// Depth image to localize from (overrides the config's `depth_source`).
    #[arg(long)]
    pub depth_source: Option<DepthSource>,
    /// LiDAR extrinsic (TOML from `harvest calibrate lidar-camera --output`), required with the
    /// `lidar-fused` depth source. The simulated unit's is `sim/lidar_extrinsic.toml`.
    #[arg(long)]
    pub lidar_extrinsic: Option<PathBuf>,
}

#[derive(Debug, thiserror::Error)]
pub enum PerceptionProcessError {
    /// The calibration, `--config` or `--lidar-extrinsic` file cannot be used (named in the
    /// message).
    #[error(transparent)]
    Config(#[from] ConfigFileError),
    /// A file this robot needs was not given: no production default stands in for it.
    #[error("{flag} FILE is required: {what}")]
    MissingFile {
        flag: &'static str,
        what: &'static str,
    },
    /// The `--laser-calibration` file cannot be used (named in the message).
    #[error(transparent)]
    LaserCalibration(#[from] harvest_laser::calibration::CalibrationFileError),
    /// `--detector` / `--model` do not fit together or with the config.
    #[error("{0}")]
    DetectorChoice(String),
    /// The detector cannot start (e.g. the ONNX model or runtime; named in the message).
    #[error(transparent)]
    Detector(#[from] harvest_perception::pipeline::PerceptionSetupError),
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// The run ended on an error (transport, wait set).
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(PerceptionProcessError);

/// Runs until SIGINT/SIGTERM.
pub fn run(
    args: &PerceptionArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<(), PerceptionProcessError> {
    run_until(args, domain, process_name, None, &AtomicBool::new(false))
}

/// The perception task these arguments describe (the camera calibration, the config and its
/// overrides, the detector, the laser's reach, the depth source), with `detector` in place of
/// the configured one when given: what the process runs, and what `harvest replay --check`
/// re-runs on a recording.
pub fn build_task(
    args: &PerceptionArgs,
    detector: Option<Box<dyn Detector + Send>>,
) -> Result<PerceptionTask, PerceptionProcessError> {
    let calibration_path =
        args.calibration
            .as_deref()
            .ok_or(PerceptionProcessError::MissingFile {
                flag: "--calibration",
                what: "the camera's pose on the robot (robot_from_camera)",
            })?;
    let calibration = Calibration::from_path(calibration_path)?;
    let mut config = match &args.config {
        Some(path) => read_config(path)?,
        None => PerceptionConfig::default(),
    };
    if let Some(kind) = args.estimator {
        config.estimator.kind = kind;
    }
    if args.no_laser {
        config.laser.enabled = false;
    }
    config
        .detector
        .override_with(args.detector, args.model.as_deref())
        .map_err(PerceptionProcessError::DetectorChoice)?;
    let detector = match detector {
        Some(detector) => detector,
        None => make_detector(&config.detector)?,
    };
    if let Some(source) = args.depth_source {
        config.depth_source = source;
    }
    let fused_depth = match config.depth_source {
        DepthSource::Tof => None,
        DepthSource::LidarFused => {
            let extrinsic_path =
                args.lidar_extrinsic
                    .as_deref()
                    .ok_or(PerceptionProcessError::MissingFile {
                        flag: "--lidar-extrinsic",
                        what: "the LiDAR's pose on the camera, for the lidar-fused depth source",
                    })?;
            let camera_from_lidar = ExtrinsicFile::read(extrinsic_path)?.camera_from_lidar;
            Some(FusedDepth::new(camera_from_lidar))
        }
    };
    let detector_name = detector.name();
    let mut node = PerceptionNode::with_detector(config.clone(), calibration, detector);
    match &args.laser_calibration {
        Some(path) => node.set_laser_reach(LaserReach::new(
            read_extrinsics(path)?,
            alacs_camera_intrinsics(),
            ALACS_FROM_TOF_CAMERA,
            ScanConfig::default(),
        )),
        None if config.laser.enabled => tracing::warn!(
            "no --laser-calibration: scans are asked for apples whatever the laser's reach"
        ),
        None => {}
    }
    tracing::info!(
        detector = detector_name,
        estimator = config.estimator.kind.name(),
        laser = config.laser.enabled,
        depth_source = ?config.depth_source,
        extrinsic = ?args.lidar_extrinsic,
        "perception configured"
    );
    Ok(PerceptionTask::new(node, fused_depth))
}

/// [`run`] with `detector` in place of the configured one (when given) that also stops once
/// `stop` is set (checked at each heartbeat, so within [`harvest_ipc::HEARTBEAT_PERIOD`]).
pub fn run_until(
    args: &PerceptionArgs,
    domain: &Domain,
    process_name: &str,
    detector: Option<Box<dyn Detector + Send>>,
    stop: &AtomicBool,
) -> Result<(), PerceptionProcessError> {
    let task = build_task(args, detector)?;
    let context = Context::new(domain, process_name)?;
    tracing::info!("perception running");
    let options = WakeOptions {
        stop: Some(stop),
        ..WakeOptions::sensor(
            Wake::Input {
                topic: CAMERA_RGBD.spec.topic,
            },
            1,
        )
    };
    let finished = run_on_wake(&context, task, (), options)?;
    let task = finished.runner.node();
    let totals = task.freshness();
    tracing::info!(
        frames = task.node().frames_processed(),
        rejected = task.node().frames_rejected(),
        frames_skipped = totals.skipped,
        max_frame_age_ns = totals.max_age_ns,
        apples = task.apples_published(),
        laser = ?task.node().laser_refiner().stats(),
        fused_depth = ?task.fused_depth().map(FusedDepth::counters),
        "perception stopped"
    );
    finished.result?;
    Ok(())
}
