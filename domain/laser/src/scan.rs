//! The ALACS perception strategy ([alacs sec. 3]): initialisation, interval scanning,
//! refinement. No IPC here: [`ScanPlanner`] says where to put the slide, [`ScanProcessor`]
//! turns each image into a candidate and picks the final position, and [`run_scan`] drives any
//! [`AlacsUnit`] through one scan ([`crate::interval_scan`]: the scan exchange by exchange).

use harvest_hw::DeviceError;
use harvest_hw::alacs::{AlacsExtrinsics, AlacsUnit, SLIDE_STROKE_M, check_slide_position};
use harvest_ipc::camera_model::CameraIntrinsics;
use serde::{Deserialize, Serialize};

use crate::candidate::{
    CandidateConfig, CandidateError, CandidateFitter, CandidatePoint, PositionCandidate, TargetHint,
};
use crate::extraction::{ExtractionConfig, ExtractionError, LaserLineExtractor};
use crate::interval_scan::{IntervalScan, drive};
use crate::selection::select_candidate;
use crate::triangulation::LaserTriangulator;

/// Shape of the interval scan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanConfig {
    /// Images per scan (paper: 5).
    pub images: usize,
    /// Slide travel between images, m (paper: 1 cm).
    pub step_m: f64,
    /// Distance from the first laser plane to the rough centre, m: positive puts the first line
    /// on the apple's left half (paper: "left half region").
    pub first_plane_to_centre_m: f64,
    /// Largest shift of the whole scan allowed to fit it inside the stroke, m.
    pub max_shift_m: f64,
}

impl Default for ScanConfig {
    fn default() -> Self {
        Self {
            images: 5,
            step_m: 0.01,
            first_plane_to_centre_m: 0.02,
            max_shift_m: 0.03,
        }
    }
}

/// Where to put the slide for each image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScanPlan {
    pub slide_positions_m: Vec<f64>,
    /// Planned distance from each laser plane to the rough centre (positive: centre right of
    /// the line), m.
    pub plane_to_centre_m: Vec<f64>,
}

/// Why no scan could be planned.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ScanPlanError {
    /// The rough centre is not finite or not in front of the camera.
    #[error("rough apple centre {centre_m:?} m is not a point in front of the ALACS camera")]
    InvalidRoughCentre { centre_m: [f64; 3] },
    /// The scan would need the slide further than the stroke allows.
    #[error(
        "the scan needs the slide from {first_m:.3} m to {last_m:.3} m, outside [0, {stroke_m}] m by more than {max_shift_m} m"
    )]
    OutOfReach {
        first_m: f64,
        last_m: f64,
        stroke_m: f64,
        max_shift_m: f64,
    },
    /// The configuration is unusable.
    #[error("scan config {name} = {value} is invalid")]
    InvalidConfig { name: &'static str, value: f64 },
}

/// Plans interval scans for one unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanPlanner {
    pub extrinsics: AlacsExtrinsics,
    pub config: ScanConfig,
}

impl ScanPlanner {
    /// The slide positions of a scan of the apple roughly at `rough_centre_in_camera_m`.
    ///
    /// The plane at `d` sits at signed distance `(n . C + L0 - d) / |n|` from `C` (eq. 4-5),
    /// so the first position is `d0 = n . C + L0 - first_plane_to_centre_m |n|`, then
    /// `d0 + k step`. A scan running off either end of the stroke is shifted inside it when the
    /// shift is at most `max_shift_m`.
    pub fn plan(&self, rough_centre_in_camera_m: [f64; 3]) -> Result<ScanPlan, ScanPlanError> {
        let config = self.config;
        if config.images == 0 {
            return Err(ScanPlanError::InvalidConfig {
                name: "images",
                value: 0.0,
            });
        }
        let span_m = config.step_m * (config.images - 1) as f64;
        if !(config.step_m.is_finite() && config.step_m >= 0.0 && span_m <= SLIDE_STROKE_M) {
            return Err(ScanPlanError::InvalidConfig {
                name: "step_m",
                value: config.step_m,
            });
        }
        let centre = rough_centre_in_camera_m;
        if !centre.iter().all(|c| c.is_finite()) || centre[2] <= 0.0 {
            return Err(ScanPlanError::InvalidRoughCentre { centre_m: centre });
        }
        let plane_home = self.extrinsics.laser_plane_in_camera(0.0);
        let normal_length = plane_home.normal.iter().map(|c| c * c).sum::<f64>().sqrt();
        let first_m = plane_home.signed_distance_m(centre) * normal_length
            - config.first_plane_to_centre_m * normal_length;
        let last_m = first_m + span_m;
        let shift_m = if first_m < 0.0 {
            -first_m
        } else if last_m > SLIDE_STROKE_M {
            SLIDE_STROKE_M - last_m
        } else {
            0.0
        };
        if shift_m.abs() > config.max_shift_m {
            return Err(ScanPlanError::OutOfReach {
                first_m,
                last_m,
                stroke_m: SLIDE_STROKE_M,
                max_shift_m: config.max_shift_m,
            });
        }
        let slide_positions_m: Vec<f64> = (0..config.images)
            .map(|k| (first_m + shift_m + k as f64 * config.step_m).clamp(0.0, SLIDE_STROKE_M))
            .collect();
        let plane_to_centre_m = slide_positions_m
            .iter()
            .map(|&d| {
                self.extrinsics
                    .laser_plane_in_camera(d)
                    .signed_distance_m(centre)
            })
            .collect();
        Ok(ScanPlan {
            slide_positions_m,
            plane_to_centre_m,
        })
    }
}

/// Tunables of [`ScanProcessor`].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProcessorConfig {
    pub extraction: ExtractionConfig,
    pub candidate: CandidateConfig,
}

/// Why one image gave no candidate.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum ImageError {
    /// The image could not be searched for the stripe.
    #[error(transparent)]
    Extraction(#[from] ExtractionError),
    /// The slide position reported with the image is outside the stroke.
    #[error("image taken at slide position {slide_position_m} m, outside the stroke")]
    SlideOutOfStroke { slide_position_m: f64 },
    /// The stripe on the target gave no candidate.
    #[error(transparent)]
    Candidate(#[from] CandidateError),
}

/// The result of one scan.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanResult {
    /// One entry per image, in scan order.
    pub candidates: Vec<Result<PositionCandidate, ImageError>>,
    /// Index of the chosen candidate.
    pub selected: usize,
    /// The final apple centre, ALACS camera frame, m.
    pub centre_in_camera_m: [f64; 3],
}

/// Turns ALACS images into position candidates; reuses its buffers across images.
#[derive(Debug, Clone)]
pub struct ScanProcessor {
    triangulator: LaserTriangulator,
    extractor: LaserLineExtractor,
    fitter: CandidateFitter,
    points: Vec<CandidatePoint>,
}

impl ScanProcessor {
    pub fn new(
        intrinsics: CameraIntrinsics,
        extrinsics: AlacsExtrinsics,
        config: ProcessorConfig,
    ) -> Result<Self, ExtractionError> {
        Ok(Self {
            triangulator: LaserTriangulator::new(intrinsics, extrinsics),
            extractor: LaserLineExtractor::new(config.extraction)?,
            fitter: CandidateFitter::new(config.candidate),
            points: Vec::new(),
        })
    }

    pub fn triangulator(&self) -> &LaserTriangulator {
        &self.triangulator
    }

    /// Every stripe point of the last image, triangulated (eq. 3, 7-8).
    pub fn last_points(&self) -> &[CandidatePoint] {
        &self.points
    }

    /// Indices into [`Self::last_points`] that the last candidate used.
    pub fn last_inliers(&self) -> &[usize] {
        self.fitter.inliers()
    }

    /// The candidate one image supports: extract the stripe in the target's box, triangulate
    /// it with the slide's reported position, fit the candidate.
    pub fn process_image(
        &mut self,
        rgb: &[u8],
        slide_position_m: f64,
        hint: &TargetHint,
    ) -> Result<PositionCandidate, ImageError> {
        self.points.clear();
        if check_slide_position(slide_position_m).is_err() {
            return Err(ImageError::SlideOutOfStroke { slide_position_m });
        }
        let intrinsics = self.triangulator.intrinsics;
        let roi = hint.roi(self.fitter.config().roi_margin_px);
        let stripe = self.extractor.extract(
            rgb,
            intrinsics.width_px as usize,
            intrinsics.height_px as usize,
            roi,
        )?;
        let triangulator = self.triangulator;
        self.points.extend(stripe.iter().filter_map(|point| {
            triangulator
                .point_from_pixel(slide_position_m, point.u_px, point.v_px)
                .map(|point_in_camera_m| CandidatePoint {
                    u_px: point.u_px,
                    v_px: point.v_px,
                    point_in_camera_m,
                })
        }));
        let plane = triangulator
            .extrinsics
            .laser_plane_in_camera(slide_position_m);
        Ok(self.fitter.fit(
            &self.points,
            &plane,
            slide_position_m,
            hint,
            0.5 * (intrinsics.fx_px + intrinsics.fy_px),
        )?)
    }

    /// Picks the final position among a scan's candidates (see [`crate::selection`]).
    pub fn select(
        candidates: Vec<Result<PositionCandidate, ImageError>>,
    ) -> Result<ScanResult, ScanFailure> {
        let selected = select_candidate(candidates.iter().map(|c| c.as_ref().ok()));
        let Some((selected, centre_in_camera_m)) = selected.and_then(|index| {
            candidates[index]
                .as_ref()
                .ok()
                .map(|candidate| (index, candidate.centre_in_camera_m))
        }) else {
            return Err(ScanFailure { candidates });
        };
        Ok(ScanResult {
            candidates,
            selected,
            centre_in_camera_m,
        })
    }
}

/// No image of the scan gave a candidate; each image's reason is kept.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("no image of the scan gave a position candidate: {}", summarize(.candidates))]
pub struct ScanFailure {
    pub candidates: Vec<Result<PositionCandidate, ImageError>>,
}

fn summarize(candidates: &[Result<PositionCandidate, ImageError>]) -> String {
    candidates
        .iter()
        .enumerate()
        .filter_map(|(index, candidate)| {
            candidate
                .as_ref()
                .err()
                .map(|error| format!("image {index}: {error}"))
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Why a scan driven by [`run_scan`] (or exchange by exchange,
/// [`crate::interval_scan::IntervalScan`]) failed.
#[derive(Debug, thiserror::Error)]
pub enum ScanError<E: DeviceError> {
    #[error(transparent)]
    Plan(#[from] ScanPlanError),
    /// The unit failed (slide, laser or camera).
    #[error("ALACS unit failed: {0}")]
    Device(#[source] E),
    #[error(transparent)]
    NoCandidate(#[from] ScanFailure),
    /// The scan was stopped before its last exchange (the emergency stop, or the end of the
    /// run), the stop having switched the laser off.
    #[error("the scan was stopped before its end (emergency stop or end of the run)")]
    Stopped,
}

/// Runs one interval scan on `unit`: plan, then for each position move the slide, capture with
/// the laser on and process the image with the *reported* slide position; the laser is
/// switched off at the end, also on failure ([`crate::interval_scan`]). `rgb` is resized to one
/// image.
pub fn run_scan<U: AlacsUnit>(
    unit: &mut U,
    planner: &ScanPlanner,
    processor: &mut ScanProcessor,
    hint: &TargetHint,
    rgb: &mut Vec<u8>,
) -> Result<ScanResult, ScanError<U::Error>> {
    let plan = planner.plan(hint.rough_centre_in_camera_m)?;
    let mut scan = IntervalScan::new(plan, *hint, None);
    drive(&mut scan, unit, processor, rgb, &mut || {});
    scan.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_starts_on_the_left_half_and_steps_one_centimetre() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let planner = ScanPlanner {
            extrinsics,
            config: ScanConfig::default(),
        };
        let centre = [-0.05, 0.02, 0.9];
        let plan = planner.plan(centre).expect("plan");
        assert_eq!(plan.slide_positions_m.len(), 5);
        for pair in plan.slide_positions_m.windows(2) {
            assert!((pair[1] - pair[0] - 0.01).abs() < 1e-12);
        }
        let beta_factor = 1.0 / (1.0 + extrinsics.beta_rad.tan().powi(2)).sqrt();
        for (k, offset) in plan.plane_to_centre_m.iter().enumerate() {
            let expected = 0.02 - k as f64 * 0.01 * beta_factor;
            assert!((offset - expected).abs() < 1e-9, "{k}: {offset}");
        }
    }

    #[test]
    fn plans_outside_the_stroke_are_shifted_or_refused() {
        let planner = ScanPlanner {
            extrinsics: AlacsExtrinsics::paper_table1(),
            config: ScanConfig::default(),
        };
        // Far right at 1.2 m needs d beyond the stroke end.
        let shifted = planner.plan([0.222, 0.0, 1.2]).expect("shifted");
        assert!(
            shifted
                .slide_positions_m
                .iter()
                .all(|d| (0.0..=SLIDE_STROKE_M).contains(d))
        );
        assert!(matches!(
            planner.plan([0.6, 0.0, 1.2]),
            Err(ScanPlanError::OutOfReach { .. })
        ));
        assert!(matches!(
            planner.plan([0.0, f64::NAN, 1.0]),
            Err(ScanPlanError::InvalidRoughCentre { .. })
        ));
    }
}
