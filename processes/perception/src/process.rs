//! `harvest perception`: `camera/rgbd` -> `perception/apples`.
//!
//! Event-driven: the wait set wakes on each frame; the frame is read in place in shared memory
//! and the detections are written in place into a loaned sample. Only the newest frame is
//! processed when several are queued: a slow detector (a learned model on a CPU) costs skipped
//! frames, never a queue. Each processed frame's age (capture to start of processing) and the
//! camera frames skipped before it are tracked ([`FreshnessTracker`]): per frame at TRACE, the
//! last age in the heartbeat (`frame_age_ns`), the totals when the process stops.
//!
//! Detector (`[detector]` in the config, or `--detector` / `--model`): built before the process
//! joins the channels, so a model that cannot be loaded, or fits no known layout, stops the
//! process at start with the reason.
//!
//! Laser refinement (`[laser]` in the config): before each frame every `laser/scan_result`
//! that has arrived is taken (never waited for); after it, the scans the frame asked for are
//! published on `laser/scan_request`. With `--laser-calibration FILE` (the ALACS unit's
//! calibration) only apples in the laser's reach are asked for
//! ([`harvest_laser::reach::LaserReach`], the same check the laser process makes).
//!
//! Depth source (`depth_source` in the config, or `--depth-source`): with `lidar_fused` the
//! process also subscribes to `lidar/points`; before each frame the newest cloud that has arrived
//! (if any) is fused into the process's depth image ([`FusedDepth`]) with the frame's geometry,
//! and the frame is localized from that image. The extrinsic is `--lidar-extrinsic FILE` (written
//! by `harvest calibrate lidar-camera --output`); it is required, as the camera calibration is.
//!
//! Colour-only frames (a GigE Vision camera, no ToF depth) need the fused source: before its
//! first cloud they are refused (warned once, counted as rejected, health degraded); with the
//! ToF source the process stops at the first such frame, saying why.

use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, alacs_camera_intrinsics};
use harvest_ipc::catalogue::{
    CAMERA_RGBD, LASER_SCAN_REQUEST, LASER_SCAN_RESULT, LIDAR_POINTS, PERCEPTION_APPLES,
};
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter,
};
use harvest_laser::calibration::read_extrinsics;
use harvest_laser::{LaserReach, ScanConfig};
use harvest_lidar::ExtrinsicFile;
use harvest_perception::calibration::Calibration;
use harvest_perception::config_file::{ConfigFileError, read_config};
use harvest_perception::depth_source::{DepthSource, FusedDepth};
use harvest_perception::detector::{Detector, DetectorKind, make_detector};
use harvest_perception::estimator::EstimatorKind;
use harvest_perception::frame_freshness::FreshnessTracker;
use harvest_perception::node::PerceptionNode;
use harvest_perception::pipeline::{PerceptionConfig, PerceptionSetupError};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

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
    /// The frames are colour only and no LiDAR depth is configured: nothing to localize from.
    #[error("{0}")]
    NoDepthSource(#[source] harvest_perception::pipeline::PerceptionSetupError),
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
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

/// [`run`] with `detector` in place of the configured one (when given) that also stops once
/// `stop` is set (checked at each heartbeat, so within [`HEARTBEAT_PERIOD`]).
pub fn run_until(
    args: &PerceptionArgs,
    domain: &Domain,
    process_name: &str,
    detector: Option<Box<dyn Detector + Send>>,
    stop: &AtomicBool,
) -> Result<(), PerceptionProcessError> {
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
    let mut fused_depth = match config.depth_source {
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

    let context = Context::new(domain, process_name)?;
    let frames = context.subscriber(CAMERA_RGBD)?;
    let mut detections = context.publisher(PERCEPTION_APPLES)?;
    let scan_results = context.subscriber(LASER_SCAN_RESULT)?;
    let mut scan_requests = context.publisher(LASER_SCAN_REQUEST)?;
    let clouds = match fused_depth {
        Some(_) => Some(context.subscriber(LIDAR_POINTS)?),
        None => None,
    };
    let mut health = HealthReporter::new(&context)?;
    let waiter = Waiter::new()?;
    let frame_guard = waiter.attach_listener(frames.listener())?;
    let heartbeat = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let mut freshness = FreshnessTracker::default();
    let mut apples_published = 0u64;
    let mut warned_no_depth = false;
    tracing::info!(
        detector = detector_name,
        estimator = config.estimator.kind.name(),
        laser = config.laser.enabled,
        depth_source = ?config.depth_source,
        extrinsic = ?args.lidar_extrinsic,
        "perception running"
    );
    waiter
        .run(|attachment| -> Result<Flow, PerceptionProcessError> {
            if attachment.has_event_from(&frame_guard)
                && let Some(frame) = frames.receive_latest()?
            {
                while let Some(result) = scan_results.receive()? {
                    let outcome = node.handle_scan_result(&result);
                    tracing::debug!(
                        request_seq = result.request_seq,
                        apple_id = result.apple_id,
                        ?outcome,
                        "laser scan result"
                    );
                }
                let fresh = freshness.start_frame(
                    frame.header.msg_seq,
                    frame.header.capture_ns,
                    MonotonicClock::read_ns(),
                );
                if let (Some(fused), Some(clouds)) = (fused_depth.as_mut(), clouds.as_ref())
                    && let Some(cloud) = clouds.receive_latest()?
                {
                    match fused.update(&frame.meta, cloud.valid_points()) {
                        Ok(stats) => tracing::debug!(
                            cloud_seq = cloud.header.msg_seq,
                            ?stats,
                            "lidar cloud fused"
                        ),
                        Err(error) => tracing::warn!(
                            cloud_seq = cloud.header.msg_seq,
                            %error,
                            "lidar cloud not fused; the previous fused depth stays in use"
                        ),
                    }
                }
                let depth_override = fused_depth
                    .as_mut()
                    .and_then(|fused| fused.depth_for(&frame.meta));
                let mut out = detections.loan()?;
                let result = node.process_with_depth(&frame, depth_override, &mut out);
                let out_seq = frame.header.msg_seq;
                out.header.capture_ns = frame.header.capture_ns;
                let count = out.apples.len();
                drop(frame);
                detections.send(out)?;
                apples_published += count as u64;
                for request in node.scan_requests() {
                    scan_requests.publish(request)?;
                }
                match result {
                    Ok(stats) => tracing::trace!(
                        frame_seq = out_seq,
                        apples = count,
                        frame_age_ns = fresh.age_ns,
                        frames_skipped = fresh.skipped,
                        detect_us = stats.timings.detect_us,
                        total_us = stats.timings.total_us,
                        "frame processed"
                    ),
                    // Colour-only frames with the ToF depth source: never any depth to use.
                    Err(error @ PerceptionSetupError::NoDepthSource { .. })
                        if fused_depth.is_none() =>
                    {
                        return Err(PerceptionProcessError::NoDepthSource(error));
                    }
                    // Colour-only frames before the first fused cloud.
                    Err(error @ PerceptionSetupError::NoDepthSource { .. }) => {
                        if !warned_no_depth {
                            tracing::warn!(%error, "frame refused: no depth yet");
                            warned_no_depth = true;
                        } else {
                            tracing::debug!(%error, "frame refused: no depth yet");
                        }
                    }
                    Err(error) => {
                        tracing::warn!(%error, "frame rejected: camera parameters unusable")
                    }
                }
            }
            if attachment.has_event_from(&heartbeat) {
                let state = if node.frames_rejected() > 0
                    && node.frames_rejected() == node.frames_processed()
                {
                    ProcessRunState::Degraded
                } else {
                    ProcessRunState::Running
                };
                health.report(
                    state,
                    frames.received_count(),
                    "frame_age_ns",
                    freshness.totals().last.age_ns,
                )?;
                if stop.load(Ordering::Relaxed) {
                    return Ok(Flow::Stop);
                }
            }
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    let totals = freshness.totals();
    tracing::info!(
        frames = node.frames_processed(),
        rejected = node.frames_rejected(),
        frames_skipped = totals.skipped,
        max_frame_age_ns = totals.max_age_ns,
        dropped_by_channel = frames.dropped_count(),
        apples = apples_published,
        laser = ?node.laser_refiner().stats(),
        fused_depth = ?fused_depth.as_ref().map(FusedDepth::counters),
        "perception stopped"
    );
    Ok(())
}
