//! The perception process's logic, free of transport and clock: one camera frame in, one
//! detections message out (plus the laser scans it asks for, and the scan results it takes
//! whenever they come). The same type runs in the `perception` process, in-process under
//! `harvest eval`, and on replayed recordings.

use crate::calibration::Calibration;
use crate::camera_setup::CameraSetup;
use crate::detector::{Detector, make_detector};
use crate::estimator::EstimatorKind;
use crate::frame::{DepthView, RgbView};
use crate::laser_refiner::{LaserRefiner, ScanResultOutcome, TrackedApple};
use crate::pipeline::{AppleEstimate, Perception, PerceptionConfig, PerceptionSetupError};
use crate::stats::FrameStats;
use harvest_ipc::payloads::apple_detections::MAX_APPLES_PER_FRAME;
use harvest_ipc::payloads::{
    AppleDetection, AppleDetections, DepthSourceCode, LaserScanRequest, LaserScanResult,
    LocalizationMethod, RgbdFrame, RgbdFrameMeta,
};

/// Perception with its rig; rebuilt when a frame's camera metadata changes.
pub struct PerceptionNode {
    config: PerceptionConfig,
    calibration: Calibration,
    pipeline: Option<(RgbdFrameMeta, Perception)>,
    /// The detector until the first pipeline is built (then the pipeline holds it, and hands it
    /// to the next one when the cameras change).
    detector: Option<Box<dyn Detector + Send>>,
    apples: Vec<AppleEstimate>,
    refiner: LaserRefiner,
    tracked: Vec<TrackedApple>,
    frames_processed: u64,
    frames_rejected: u64,
}

impl PerceptionNode {
    /// A node whose detector is built from `config.detector` with the first frame (a detector
    /// that cannot be built rejects every frame; processes build it first with
    /// [`Self::with_detector`] to refuse a bad model at start).
    pub fn new(config: PerceptionConfig, calibration: Calibration) -> Self {
        Self::build(config, calibration, None)
    }

    /// A node running `detector` (built by [`make_detector`] from `config.detector`, or a
    /// test's).
    pub fn with_detector(
        config: PerceptionConfig,
        calibration: Calibration,
        detector: Box<dyn Detector + Send>,
    ) -> Self {
        Self::build(config, calibration, Some(detector))
    }

    fn build(
        config: PerceptionConfig,
        calibration: Calibration,
        detector: Option<Box<dyn Detector + Send>>,
    ) -> Self {
        let refiner = LaserRefiner::new(config.laser);
        Self {
            config,
            calibration,
            pipeline: None,
            detector,
            apples: Vec::new(),
            refiner,
            tracked: Vec::new(),
            frames_processed: 0,
            frames_rejected: 0,
        }
    }

    pub fn frames_processed(&self) -> u64 {
        self.frames_processed
    }

    /// Frames rejected as a whole (bad size, bad camera parameters).
    pub fn frames_rejected(&self) -> u64 {
        self.frames_rejected
    }

    /// The laser scans asked for by the last [`Self::process`] call, to publish on
    /// `laser/scan_request`.
    pub fn scan_requests(&self) -> &[LaserScanRequest] {
        self.refiner.requests()
    }

    /// Takes a `laser/scan_result`: the apple that asked for it is published at the scan's
    /// position from its next detection on. Never blocks.
    pub fn handle_scan_result(&mut self, result: &LaserScanResult) -> ScanResultOutcome {
        self.refiner
            .handle_result(result, &self.calibration.camera.robot_from_camera)
    }

    /// Asks the laser only for apples in its reach (see [`LaserRefiner::set_reach`]).
    pub fn set_laser_reach(&mut self, reach: harvest_laser::LaserReach) {
        self.refiner.set_reach(reach);
    }

    /// Tracks, scan policy and their counters.
    pub fn laser_refiner(&self) -> &LaserRefiner {
        &self.refiner
    }

    /// The apples of the last frame as estimated from the ToF frame alone (before any laser
    /// refinement), in the order of the published detections.
    pub fn last_estimates(&self) -> &[AppleEstimate] {
        &self.apples
    }

    /// Detects and localizes the apples of `frame` into `out` (which may be loaned shared
    /// memory; every field of it is written). Apples carry their track id as `apple_id`; a
    /// laser-refined apple is published at the scan's position with method `LaserScan`. Scans
    /// to ask for are in [`Self::scan_requests`] afterwards. Returns the frame's statistics,
    /// or the setup error when the frame's camera parameters are unusable (then `out` holds no
    /// apples).
    pub fn process(
        &mut self,
        frame: &RgbdFrame,
        out: &mut AppleDetections,
    ) -> Result<FrameStats, PerceptionSetupError> {
        self.process_with_depth(frame, None, out)
    }

    /// [`Self::process`] with `depth_mm_override` (when given) in place of the frame's depth
    /// image: the same layout (the frame's depth intrinsics, millimetres, 0 = no return), e.g.
    /// the LiDAR-fused depth of [`crate::depth_source::FusedDepth`]. Apples localized from an
    /// override are published with depth source `LidarFused` (laser-refined ones `LaserLine`).
    /// An override of another size rejects the frame, and so does a colour-only frame
    /// (`RgbdFrameMeta::FLAG_COLOR_ONLY`) without an override: it has no depth of its own
    /// ([`PerceptionSetupError::NoDepthSource`]).
    pub fn process_with_depth(
        &mut self,
        frame: &RgbdFrame,
        depth_mm_override: Option<&[u16]>,
        out: &mut AppleDetections,
    ) -> Result<FrameStats, PerceptionSetupError> {
        out.source_frame_seq = frame.header.msg_seq;
        out.source_capture_ns = frame.header.capture_ns;
        out.processing_ns = 0;
        out.apples.clear();
        self.refiner.clear_requests();
        self.frames_processed += 1;
        if depth_mm_override.is_none() && frame.meta.is_color_only() {
            self.frames_rejected += 1;
            return Err(PerceptionSetupError::NoDepthSource {
                frame_seq: frame.header.msg_seq,
            });
        }
        if let Some(depth) = depth_mm_override
            && depth.len() != frame.depth_mm.len()
        {
            self.frames_rejected += 1;
            return Err(PerceptionSetupError::DepthOverrideSize {
                expected: frame.depth_mm.len(),
                actual: depth.len(),
            });
        }
        let mut apples = std::mem::take(&mut self.apples);
        let perception = match self.pipeline_for(&frame.meta) {
            Ok(perception) => perception,
            Err(error) => {
                self.frames_rejected += 1;
                self.apples = apples;
                return Err(error);
            }
        };
        let rgb = RgbView {
            width_px: frame.meta.rgb_intrinsics.width_px,
            height_px: frame.meta.rgb_intrinsics.height_px,
            data: &frame.rgb,
        };
        let depth = DepthView {
            width_px: frame.meta.depth_intrinsics.width_px,
            height_px: frame.meta.depth_intrinsics.height_px,
            data: depth_mm_override.unwrap_or(&frame.depth_mm),
        };
        let stats = perception.process_into(&rgb, &depth, &mut apples).clone();
        if stats.rejection.is_some() {
            self.frames_rejected += 1;
        }
        let color = &frame.meta.rgb_intrinsics;
        let color_focal_px = 0.5 * (color.fx_px + color.fy_px);
        self.refiner.update(
            &apples,
            color_focal_px,
            frame.header.capture_ns,
            &mut self.tracked,
        );
        out.processing_ns = stats.timings.total_us * 1000;
        let depth_source = if depth_mm_override.is_some() {
            DepthSourceCode::LidarFused
        } else {
            DepthSourceCode::Tof
        };
        for (apple, tracked) in apples.iter().zip(&self.tracked).take(MAX_APPLES_PER_FRAME) {
            let (method, depth_source, position_in_camera_m, position_in_robot_m) =
                match tracked.laser_position_m {
                    Some((camera, robot)) => (
                        LocalizationMethod::LaserScan,
                        DepthSourceCode::LaserLine,
                        camera,
                        robot,
                    ),
                    None => (
                        localization_method(apple.estimator),
                        depth_source,
                        apple.position_in_camera_m,
                        apple.position_in_robot_m,
                    ),
                };
            let detection = AppleDetection {
                apple_id: tracked.apple_id,
                method: method.into(),
                depth_source: depth_source.into(),
                _reserved: [0; 2],
                position_in_camera_m,
                position_in_robot_m,
                radius_m: apple.radius_m,
                confidence: apple.confidence,
                box_px: [
                    apple.pixel_box.u_min_px,
                    apple.pixel_box.v_min_px,
                    apple.pixel_box.width_px(),
                    apple.pixel_box.height_px(),
                ],
                visible_px: apple.visible_px,
            };
            if out.apples.push(detection).is_err() {
                break;
            }
        }
        self.apples = apples;
        Ok(stats)
    }

    fn pipeline_for(
        &mut self,
        meta: &RgbdFrameMeta,
    ) -> Result<&mut Perception, PerceptionSetupError> {
        let perception = match self.pipeline.take() {
            Some((built_for, perception)) if built_for == *meta => perception,
            previous => {
                let cameras = CameraSetup {
                    color: meta.rgb_intrinsics,
                    depth: meta.depth_intrinsics,
                    color_from_depth: meta.color_from_depth,
                    robot_from_camera: self.calibration.camera.robot_from_camera,
                };
                let detector = match previous {
                    Some((_, old)) => old.into_detector(),
                    None => match self.detector.take() {
                        Some(detector) => detector,
                        None => make_detector(&self.config.detector)?,
                    },
                };
                // A refused camera setup keeps the detector for the next frame.
                let config = self.config.clone();
                match Perception::try_with_detector(config, cameras, detector) {
                    Ok(perception) => perception,
                    Err((error, detector)) => {
                        self.detector = Some(detector);
                        return Err(error);
                    }
                }
            }
        };
        let (_, perception) = self.pipeline.insert((*meta, perception));
        Ok(perception)
    }
}

/// The wire code of an estimator.
pub fn localization_method(kind: EstimatorKind) -> LocalizationMethod {
    match kind {
        EstimatorKind::ClusterDepth => LocalizationMethod::ClusterCentroid,
        EstimatorKind::SphereFit => LocalizationMethod::SphereFit,
        EstimatorKind::ZScoreCentroid => LocalizationMethod::ZScoreCentroid,
    }
}
