//! The perception pipeline of one ToF camera: detections -> mask points -> apple positions.
//!
//! Implements [dual-arm sec. 3.1] with a pluggable detector and estimator. Per frame:
//! 1. Both frames are checked against the calibrated sizes; a malformed frame yields no apples and
//!    is counted ([`FrameStats::rejection`]).
//! 2. The detector finds apples in the colour image; detections below `min_detection_confidence`
//!    (0.3 in the paper) are dropped.
//! 3. The masks are painted into a label image (2x2-pixel cells; where masks overlap the more
//!    confident detection wins) and every registered depth sample is assigned to the detection
//!    under it: the mask points.
//! 4. The estimator turns each detection's points and box-centre ray into a position; positions
//!    that are non-finite or outside the camera's working range are dropped.
//!    An estimator may find several fruit in one mask (fruit hidden behind fruit); each then gets
//!    the box of its sphere's image and a share of the mask's visible pixels.
//!    Over-exposed blob detections (no colour evidence) are located by
//!    [`crate::blob_localization`] (not by the sphere fit: sunlight degrades their depth) except
//!    under the paper's estimator, and kept only when depth confirms an apple-sized, curved,
//!    centred object ([`crate::estimate_checks::SaturatedBlobCheck`]). An estimate whose centre
//!    disagrees with its mask's median depth ([`crate::estimate_checks::depth_agrees`]) is
//!    dropped.
//! 5. Estimates of one fruit split by an occluder into several detections (the paper's
//!    over-detection, 4.3) are merged when their centres are closer than
//!    `duplicate_distance_radii` times the sum of their radii (each at least
//!    `duplicate_min_radius_m`), and re-estimated from the union of their points.
//! 6. Colour and model detections whose mask covers less than `min_visible_fraction` of their fitted
//!    fruit's image disc are dropped (fragments of mostly hidden fruit localize poorly), and so
//!    are apples whose confidence (mask confidence times position confidence) is below
//!    `min_output_confidence` (mostly fallback estimates from few points).
//! 7. Each apple is reported in the colour camera frame and, via `robot_from_camera`, in the robot
//!    frame ([fusion eq. 20]).
//!
//! Layout: `config` and `error` (building the pipeline), `apple_estimate` (its output), one file
//! per stage that needs more than a few lines: `mask_points` (step 3), `estimation` (step 4),
//! `merge` (step 5); steps 1-2, 6 and 7 are in this file.

mod apple_estimate;
mod config;
mod error;
mod estimation;
mod mask_points;
mod merge;

pub use apple_estimate::AppleEstimate;
pub use config::PerceptionConfig;
pub use error::PerceptionSetupError;

use std::time::Instant;

use tracing::{debug, trace};

use crate::blob_localization::BlobLocalizer;
use crate::camera_setup::CameraSetup;
use crate::detector::{Detection, DetectionSource, Detector, make_detector};
use crate::estimate_checks::{SaturatedBlobCheck, visible_fraction};
use crate::estimator::{Estimator, EstimatorContext, PositionEstimate, make_estimator};
use crate::frame::{DepthView, RgbView};
use crate::registration::DepthRegistration;
use crate::stats::{FrameStats, PerceptionStats};
use mask_points::LABEL_CELL_PX;
use merge::Pending;

/// The perception pipeline with its scratch buffers. Not thread-safe by itself; one instance per
/// camera stream.
pub struct Perception {
    config: PerceptionConfig,
    cameras: CameraSetup,
    detector: Box<dyn Detector + Send>,
    estimator: Box<dyn Estimator + Send>,
    registration: DepthRegistration,
    detections: Vec<Detection>,
    active: Vec<usize>,
    label_map: Vec<u16>,
    label_width: usize,
    label_height: usize,
    points: Vec<Vec<[f32; 3]>>,
    merged_points: Vec<[f32; 3]>,
    estimates: Vec<PositionEstimate>,
    pending: Vec<Pending>,
    /// Detection indices of each pending estimate (`pending_members[k]` lists detections).
    pending_members: Vec<Vec<usize>>,
    accepted: Vec<usize>,
    depth_scratch: Vec<f32>,
    blob_localizer: BlobLocalizer,
    blob_check: SaturatedBlobCheck,
    last: FrameStats,
    totals: PerceptionStats,
}

impl std::fmt::Debug for Perception {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Perception")
            .field("config", &self.config)
            .field("cameras", &self.cameras)
            .field("detector", &self.detector.name())
            .field("estimator", &self.estimator.kind())
            .field("totals", &self.totals)
            .finish_non_exhaustive()
    }
}

impl Perception {
    /// A pipeline with the configured detector (`config.detector`).
    pub fn new(
        config: PerceptionConfig,
        cameras: CameraSetup,
    ) -> Result<Self, PerceptionSetupError> {
        let detector = make_detector(&config.detector)?;
        Self::with_detector(config, cameras, detector)
    }

    /// The pipeline's detector, for a pipeline rebuilt for other cameras (a learned detector's
    /// model is loaded once).
    pub fn into_detector(self) -> Box<dyn Detector + Send> {
        self.detector
    }

    /// A pipeline with a caller-supplied detector (built by [`make_detector`], or a test's).
    pub fn with_detector(
        config: PerceptionConfig,
        cameras: CameraSetup,
        detector: Box<dyn Detector + Send>,
    ) -> Result<Self, PerceptionSetupError> {
        Self::try_with_detector(config, cameras, detector).map_err(|(error, _)| error)
    }

    /// [`Self::with_detector`] that hands the detector back when the setup is refused.
    #[allow(clippy::result_large_err)]
    pub fn try_with_detector(
        config: PerceptionConfig,
        cameras: CameraSetup,
        detector: Box<dyn Detector + Send>,
    ) -> Result<Self, (PerceptionSetupError, Box<dyn Detector + Send>)> {
        let estimator = match Self::checked_estimator(&config, &cameras) {
            Ok(estimator) => estimator,
            Err(error) => return Err((error, detector)),
        };
        let registration = DepthRegistration::new(
            cameras.depth,
            cameras.color,
            cameras.color_from_depth,
            config.depth_range,
        );
        let label_width = cameras.color.width_px.div_ceil(LABEL_CELL_PX) as usize;
        let label_height = cameras.color.height_px.div_ceil(LABEL_CELL_PX) as usize;
        let blob_check = SaturatedBlobCheck {
            depth_samples_per_color_px: (cameras.depth.fx_px * cameras.depth.fy_px)
                / (cameras.color.fx_px * cameras.color.fy_px),
            color_focal_px: 0.5 * (cameras.color.fx_px + cameras.color.fy_px),
            min_depth_coverage: config.saturated_blob_min_depth_coverage,
            radius_range_m: config.saturated_blob_radius_m,
        };
        Ok(Self {
            config,
            cameras,
            detector,
            estimator,
            registration,
            detections: Vec::new(),
            active: Vec::new(),
            label_map: vec![0; label_width * label_height],
            label_width,
            label_height,
            points: Vec::new(),
            merged_points: Vec::new(),
            estimates: Vec::new(),
            pending: Vec::new(),
            pending_members: Vec::new(),
            accepted: Vec::new(),
            depth_scratch: Vec::new(),
            blob_localizer: BlobLocalizer::default(),
            blob_check,
            last: FrameStats::default(),
            totals: PerceptionStats::default(),
        })
    }

    /// Checks the settings and cameras and builds the estimator.
    fn checked_estimator(
        config: &PerceptionConfig,
        cameras: &CameraSetup,
    ) -> Result<Box<dyn Estimator + Send>, PerceptionSetupError> {
        cameras.validate()?;
        config.depth_range.validate()?;
        config.laser.validate()?;
        let checks = [
            (
                "min_detection_confidence",
                f64::from(config.min_detection_confidence),
                0.0,
                1.0,
            ),
            (
                "duplicate_distance_radii",
                config.duplicate_distance_radii,
                0.0,
                2.0,
            ),
            (
                "min_points_per_apple",
                f64::from(config.min_points_per_apple),
                1.0,
                1e6,
            ),
            (
                "duplicate_min_radius_m",
                config.duplicate_min_radius_m,
                0.0,
                0.5,
            ),
            (
                "min_output_confidence",
                f64::from(config.output_confidence_threshold()),
                0.0,
                1.0,
            ),
            (
                "min_visible_fraction",
                config.min_visible_fraction,
                0.0,
                1.0,
            ),
            (
                "depth_agreement_sigmas",
                config.depth_agreement_sigmas,
                0.0,
                1e3,
            ),
            (
                "saturated_blob_min_depth_coverage",
                config.saturated_blob_min_depth_coverage,
                0.0,
                1.0,
            ),
            (
                "saturated_blob_radius_m[0]",
                config.saturated_blob_radius_m[0],
                0.0,
                config.saturated_blob_radius_m[1],
            ),
            (
                "saturated_blob_radius_m[1]",
                config.saturated_blob_radius_m[1],
                config.saturated_blob_radius_m[0],
                1.0,
            ),
            (
                "saturated_blob_max_flatness",
                config.saturated_blob_max_flatness,
                0.0,
                1e3,
            ),
            (
                "saturated_blob_max_asymmetry",
                config.saturated_blob_max_asymmetry,
                0.0,
                1e3,
            ),
            (
                "saturated_blob_position_confidence",
                f64::from(config.saturated_blob_position_confidence),
                0.0,
                1.0,
            ),
        ];
        for (key, value, min, max) in checks {
            if !value.is_finite() || value < min || value > max {
                return Err(PerceptionSetupError::OutOfRange {
                    key,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(make_estimator(
            &config.estimator,
            EstimatorContext {
                noise: config.depth_noise(),
                depth_focal_px: cameras.depth.fx_px,
            },
        )?)
    }

    pub fn config(&self) -> &PerceptionConfig {
        &self.config
    }

    pub fn cameras(&self) -> &CameraSetup {
        &self.cameras
    }

    /// Statistics of the last processed frame.
    pub fn last_frame_stats(&self) -> &FrameStats {
        &self.last
    }

    /// Statistics accumulated since construction.
    pub fn stats(&self) -> &PerceptionStats {
        &self.totals
    }

    /// The 2D detections of the last frame (all of them, before the confidence threshold).
    pub fn detections(&self) -> &[Detection] {
        &self.detections
    }

    /// Localizes the apples in one RGB-D frame. Bad input yields fewer (or no) apples, never a
    /// panic; see [`Self::last_frame_stats`].
    pub fn process(&mut self, rgb: &RgbView<'_>, depth: &DepthView<'_>) -> Vec<AppleEstimate> {
        let mut apples = Vec::new();
        self.process_into(rgb, depth, &mut apples);
        apples
    }

    /// Like [`Self::process`], reusing `apples` (cleared first).
    pub fn process_into(
        &mut self,
        rgb: &RgbView<'_>,
        depth: &DepthView<'_>,
        apples: &mut Vec<AppleEstimate>,
    ) -> &FrameStats {
        apples.clear();
        let start = Instant::now();
        let mut stats = FrameStats::default();
        self.run(rgb, depth, apples, &mut stats, start);
        stats.apples = apples.len() as u32;
        stats.timings.total_us = start.elapsed().as_micros() as u64;
        trace!(
            apples = stats.apples,
            detections = stats.detections,
            registered = stats.depth_registered_px,
            total_us = stats.timings.total_us,
            "perception frame"
        );
        self.totals.accumulate(&stats);
        self.last = stats;
        &self.last
    }

    fn run(
        &mut self,
        rgb: &RgbView<'_>,
        depth: &DepthView<'_>,
        apples: &mut Vec<AppleEstimate>,
        stats: &mut FrameStats,
        start: Instant,
    ) {
        self.detections.clear();
        let frame_check = rgb
            .validate_size(self.cameras.color.width_px, self.cameras.color.height_px)
            .and_then(|()| {
                depth.validate_size(self.cameras.depth.width_px, self.cameras.depth.height_px)
            });
        if let Err(error) = frame_check {
            debug!(%error, "frame rejected");
            stats.rejection = Some(error);
            return;
        }
        match self.detector.detect(rgb, &mut self.detections) {
            Ok(info) => stats.saturated_fraction = info.saturated_fraction,
            Err(error) => {
                debug!(%error, detector = self.detector.name(), "frame rejected by the detector");
                stats.rejection = Some(error);
                self.detections.clear();
                return;
            }
        }
        stats.detections = self.detections.len() as u32;
        let after_detect = Instant::now();
        stats.timings.detect_us = (after_detect - start).as_micros() as u64;

        self.active.clear();
        let limit = usize::from(u16::MAX - 1);
        for (index, detection) in self.detections.iter().enumerate() {
            if detection.confidence >= self.config.min_detection_confidence
                && detection.confidence.is_finite()
                && self.active.len() < limit
            {
                self.active.push(index);
            } else {
                stats.detections_below_confidence += 1;
            }
        }
        self.paint_labels();
        self.collect_points(depth, stats);
        let after_register = Instant::now();
        stats.timings.register_us = (after_register - after_detect).as_micros() as u64;

        self.estimate_detections(stats);
        if self.config.merge_duplicates {
            self.merge_duplicates(stats);
        } else {
            self.accepted.clear();
            self.accepted.extend(0..self.pending.len());
        }
        let robot_from_camera = self.cameras.robot_from_camera;
        let kind = self.estimator.kind();
        for &k in &self.accepted {
            let p = &self.pending[k];
            let hidden = p.source != DetectionSource::SaturatedBlob
                && visible_fraction(
                    p.visible_px,
                    p.estimate.radius_m,
                    p.estimate.position_in_camera_m[2],
                    self.blob_check.color_focal_px,
                ) < self.config.min_visible_fraction;
            if hidden {
                stats.estimates_mostly_hidden += 1;
                continue;
            }
            let confidence = p.mask_confidence * p.estimate.confidence;
            if confidence.is_nan() || confidence < self.config.output_confidence_threshold() {
                stats.estimates_below_confidence += 1;
                continue;
            }
            stats.estimates_fallback += u32::from(p.estimate.fallback);
            apples.push(AppleEstimate {
                pixel_box: p.pixel_box,
                visible_px: p.visible_px,
                mask_confidence: p.mask_confidence,
                position_confidence: p.estimate.confidence,
                confidence,
                position_in_camera_m: p.estimate.position_in_camera_m,
                position_in_robot_m: robot_from_camera.apply(p.estimate.position_in_camera_m),
                radius_m: p.estimate.radius_m,
                points_used: p.estimate.points_used,
                estimator: kind,
                fallback: p.estimate.fallback,
                detections_merged: p.detections_merged,
            });
        }
        stats.timings.estimate_us = after_register.elapsed().as_micros() as u64;
    }
}

#[cfg(test)]
mod tests;
