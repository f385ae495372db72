//! Localisation accuracy of a calibrated ALACS, measured the way [alacs sec. 5.2] does
//! (Figure 7), on rendered images instead of a checkerboard.
//!
//! For each slide position `d` (paper: 0, 5, 10, 15, 20 cm) and each target depth between 0.6
//! and 1.2 m, an apple is placed so that the laser line crosses its left half, sometimes behind
//! a leaf, in front of a canopy plane; the image is rendered with the *true* extrinsics and
//! sensor noise, then processed with the *calibrated* extrinsics exactly as a scan image is.
//! For every stripe point the candidate used, the triangulated point (eq. 3, 7-8) is compared
//! with the true surface point along the same pixel's ray (the paper's reference is likewise the
//! board point on the pixel's ray). Reported: max and mean |error| per axis, against the paper's
//! worst case of 0.6 / 1.2 / 4 mm (x / y / z). The apple-centre candidates' errors are reported
//! too.
//!
//! The paper's worst case is a maximum over 30 samples per slide position: 3 laser points chosen
//! at random from each of 10 images. Beside the maximum over every stripe point (a thousand per
//! position, so a much deeper tail), the same statistic is reported: 3 stripe points drawn at
//! random per image (`paper_sample`, from its own random stream so the scenes do not change).

use harvest_hw::alacs::{AlacsError, AlacsExtrinsics};
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_sim::alacs::{
    AlacsRenderer, AlacsScene, AppleSphere, LaserRenderParams, LeafDisc, SurfaceId,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

use harvest_laser::candidate::TargetHint;
use harvest_laser::extraction::{ExtractionError, PixelRoi};
use harvest_laser::scan::{ProcessorConfig, ScanProcessor};
use harvest_laser::triangulation::LaserTriangulator;

/// The paper's worst-case localisation errors (x, y, z), mm (section 5.2).
pub const PAPER_MAX_ERROR_MM: [f64; 3] = [0.6, 1.2, 4.0];

/// What to render.
#[derive(Debug, Clone, PartialEq)]
pub struct AccuracyConfig {
    /// Slide positions evaluated, m.
    pub slide_positions_m: Vec<f64>,
    /// Target depths per slide position, evenly spaced over `[nearest_m, farthest_m]`.
    pub depths: usize,
    pub nearest_m: f64,
    pub farthest_m: f64,
    pub apple_radius_m: f64,
    /// Distance from the laser plane to the apple centre (line on the left half), m.
    pub plane_to_centre_m: f64,
    /// Chance that a leaf hides part of the apple.
    pub leaf_probability: f64,
    /// Sensor and stripe appearance (noise included).
    pub render: LaserRenderParams,
    /// Noise of the detection box edges, pixels.
    pub bbox_sigma_px: f64,
    /// Noise of the rough (RGB-D) centre per axis, m.
    pub rough_sigma_m: [f64; 3],
    pub seed: u64,
}

impl Default for AccuracyConfig {
    fn default() -> Self {
        Self {
            slide_positions_m: vec![0.0, 0.05, 0.10, 0.15, 0.20],
            depths: 10,
            nearest_m: 0.6,
            farthest_m: 1.2,
            apple_radius_m: 0.04,
            plane_to_centre_m: 0.02,
            leaf_probability: 0.3,
            render: LaserRenderParams::default(),
            bbox_sigma_px: 1.0,
            rough_sigma_m: [0.005, 0.005, 0.015],
            seed: 1,
        }
    }
}

/// Absolute errors per axis.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct AxisErrors {
    pub count: usize,
    pub max_abs_mm: [f64; 3],
    pub mean_abs_mm: [f64; 3],
}

impl AxisErrors {
    fn add(&mut self, estimate: [f64; 3], truth: [f64; 3]) {
        let previous = self.count as f64;
        self.count += 1;
        for axis in 0..3 {
            let error_mm = (estimate[axis] - truth[axis]).abs() * 1e3;
            self.max_abs_mm[axis] = self.max_abs_mm[axis].max(error_mm);
            self.mean_abs_mm[axis] =
                (self.mean_abs_mm[axis] * previous + error_mm) / self.count as f64;
        }
    }

    fn merge(&mut self, other: &Self) {
        let total = self.count + other.count;
        if total == 0 {
            return;
        }
        for axis in 0..3 {
            self.max_abs_mm[axis] = self.max_abs_mm[axis].max(other.max_abs_mm[axis]);
            self.mean_abs_mm[axis] = (self.mean_abs_mm[axis] * self.count as f64
                + other.mean_abs_mm[axis] * other.count as f64)
                / total as f64;
        }
        self.count = total;
    }

    /// True when every axis's max is within the paper's worst case.
    pub fn within_paper(&self) -> bool {
        (0..3).all(|axis| self.max_abs_mm[axis] <= PAPER_MAX_ERROR_MM[axis])
    }
}

/// Results at one slide position.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SlideAccuracy {
    pub slide_position_m: f64,
    pub images: usize,
    pub images_with_candidate: usize,
    /// Stripe points triangulated with the calibrated extrinsics.
    pub points: AxisErrors,
    /// The same points triangulated with the true extrinsics (extraction error alone).
    pub points_true_extrinsics: AxisErrors,
    /// Apple-centre candidates.
    pub centres: AxisErrors,
    /// Three stripe points drawn at random per image (the paper's 30 samples per position),
    /// calibrated extrinsics.
    pub paper_sample: AxisErrors,
    /// Used stripe points whose pixel ray does not hit the target apple.
    pub misattributed_points: usize,
}

/// The whole evaluation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AccuracyReport {
    pub per_slide: Vec<SlideAccuracy>,
    pub points: AxisErrors,
    pub points_true_extrinsics: AxisErrors,
    pub centres: AxisErrors,
    /// Three random stripe points per image, all positions (the paper's protocol).
    pub paper_sample: AxisErrors,
    pub paper_max_mm: [f64; 3],
}

/// Stripe points the paper takes per image (section 5.2).
pub const PAPER_POINTS_PER_IMAGE: usize = 3;

/// Decorrelates the paper-sample draws from the scene stream.
const PAPER_SAMPLE_STREAM: u64 = 0x5a3c_9e1d_27b4_f60b;

/// Why the evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum AccuracyError {
    #[error("rendering failed: {0}")]
    Render(#[from] AlacsError),
    #[error(transparent)]
    Processor(#[from] ExtractionError),
    #[error("accuracy config {name} = {value} is invalid")]
    InvalidConfig { name: &'static str, value: f64 },
}

/// Runs the evaluation (see the module docs). `truth` renders, `calibrated` measures.
pub fn evaluate_localization_accuracy(
    intrinsics: CameraIntrinsics,
    truth: &AlacsExtrinsics,
    calibrated: &AlacsExtrinsics,
    config: &AccuracyConfig,
) -> Result<AccuracyReport, AccuracyError> {
    let checks = [
        ("depths", config.depths as f64, config.depths > 0),
        (
            "nearest_m",
            config.nearest_m,
            config.nearest_m > config.apple_radius_m,
        ),
        (
            "farthest_m",
            config.farthest_m,
            config.farthest_m >= config.nearest_m,
        ),
        (
            "apple_radius_m",
            config.apple_radius_m,
            config.apple_radius_m > 0.0,
        ),
        (
            "leaf_probability",
            config.leaf_probability,
            (0.0..=1.0).contains(&config.leaf_probability),
        ),
        (
            "bbox_sigma_px",
            config.bbox_sigma_px,
            config.bbox_sigma_px >= 0.0,
        ),
    ];
    for (name, value, valid) in checks {
        if !valid || !value.is_finite() {
            return Err(AccuracyError::InvalidConfig { name, value });
        }
    }
    let renderer = AlacsRenderer::new(intrinsics)?;
    let mut processor = ScanProcessor::new(intrinsics, *calibrated, ProcessorConfig::default())?;
    let ideal = LaserTriangulator::new(intrinsics, *truth);
    let mut rng = SmallRng::seed_from_u64(config.seed);
    let mut sample_rng = SmallRng::seed_from_u64(config.seed ^ PAPER_SAMPLE_STREAM);
    let mut image_points: Vec<([f64; 3], [f64; 3])> = Vec::new();
    let unit_normal = Normal::new(0.0, 1.0).map_err(|_| AccuracyError::InvalidConfig {
        name: "normal",
        value: 1.0,
    })?;
    let mut rgb = vec![0; renderer.image_len()];
    let mut per_slide = Vec::with_capacity(config.slide_positions_m.len());
    let mut frame = 0_u64;
    for &slide_position_m in &config.slide_positions_m {
        let mut result = SlideAccuracy {
            slide_position_m,
            images: 0,
            images_with_candidate: 0,
            points: AxisErrors::default(),
            points_true_extrinsics: AxisErrors::default(),
            centres: AxisErrors::default(),
            paper_sample: AxisErrors::default(),
            misattributed_points: 0,
        };
        for depth_index in 0..config.depths {
            let fraction = if config.depths > 1 {
                depth_index as f64 / (config.depths - 1) as f64
            } else {
                0.5
            };
            let depth_m = config.nearest_m + fraction * (config.farthest_m - config.nearest_m);
            let Some(apple) = place_apple(
                &intrinsics,
                truth,
                slide_position_m,
                depth_m,
                config,
                &mut rng,
            ) else {
                continue;
            };
            let scene = scene_around(apple, config, &mut rng);
            let params = LaserRenderParams {
                noise_seed: config.render.noise_seed.wrapping_add(frame),
                ..config.render
            };
            frame += 1;
            renderer.render(truth, slide_position_m, &scene, &params, &mut rgb)?;
            result.images += 1;

            let centre = apple.centre_in_camera_m;
            let hint = TargetHint {
                bbox_px: noisy_bbox(
                    &intrinsics,
                    &apple,
                    config.bbox_sigma_px,
                    &unit_normal,
                    &mut rng,
                ),
                rough_centre_in_camera_m: [0, 1, 2].map(|axis| {
                    centre[axis] + config.rough_sigma_m[axis] * unit_normal.sample(&mut rng)
                }),
            };
            let Ok(candidate) = processor.process_image(&rgb, slide_position_m, &hint) else {
                continue;
            };
            result.images_with_candidate += 1;
            result.centres.add(candidate.centre_in_camera_m, centre);
            let points = processor.last_points();
            image_points.clear();
            for &index in processor.last_inliers() {
                let point = &points[index];
                let (u_bar, v_bar) = intrinsics.normalize(point.u_px, point.v_px);
                let hit = scene.ray_cast([0.0; 3], [u_bar, v_bar, 1.0]);
                let Some(hit) = hit.filter(|hit| hit.surface == SurfaceId::Apple(0)) else {
                    result.misattributed_points += 1;
                    continue;
                };
                result
                    .points
                    .add(point.point_in_camera_m, hit.point_in_camera_m);
                image_points.push((point.point_in_camera_m, hit.point_in_camera_m));
                if let Some(ideal_point) =
                    ideal.point_from_pixel(slide_position_m, point.u_px, point.v_px)
                {
                    result
                        .points_true_extrinsics
                        .add(ideal_point, hit.point_in_camera_m);
                }
            }
            let draws = PAPER_POINTS_PER_IMAGE.min(image_points.len());
            for index in rand::seq::index::sample(&mut sample_rng, image_points.len(), draws) {
                let (estimate, truth_point) = image_points[index];
                result.paper_sample.add(estimate, truth_point);
            }
        }
        tracing::debug!(?result, "ALACS accuracy at one slide position");
        per_slide.push(result);
    }
    let mut points = AxisErrors::default();
    let mut points_true_extrinsics = AxisErrors::default();
    let mut centres = AxisErrors::default();
    let mut paper_sample = AxisErrors::default();
    for slide in &per_slide {
        points.merge(&slide.points);
        points_true_extrinsics.merge(&slide.points_true_extrinsics);
        centres.merge(&slide.centres);
        paper_sample.merge(&slide.paper_sample);
    }
    Ok(AccuracyReport {
        per_slide,
        points,
        points_true_extrinsics,
        centres,
        paper_sample,
        paper_max_mm: PAPER_MAX_ERROR_MM,
    })
}

/// An apple at `depth_m` whose centre lies `plane_to_centre_m` right of the laser plane, at a
/// random height, fully inside the image; `None` if no height fits.
fn place_apple(
    intrinsics: &CameraIntrinsics,
    truth: &AlacsExtrinsics,
    slide_position_m: f64,
    depth_m: f64,
    config: &AccuracyConfig,
    rng: &mut SmallRng,
) -> Option<AppleSphere> {
    let plane = truth.laser_plane_in_camera(slide_position_m);
    let normal = plane.unit_normal();
    let (sin_a, cos_a) = truth.alpha_rad.sin_cos();
    let radius_m = config.apple_radius_m;
    for _ in 0..20 {
        let y_m = rng.random_range(-0.2..=0.2) * depth_m;
        let x_m =
            (depth_m * sin_a - truth.baseline_m(slide_position_m) - y_m * truth.beta_rad.tan())
                / cos_a;
        let centre = [0, 1, 2]
            .map(|axis| [x_m, y_m, depth_m][axis] + config.plane_to_centre_m * normal[axis]);
        let margin_m = 1.3 * radius_m;
        let inside = [[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]]
            .iter()
            .all(|[dx, dy]| {
                intrinsics
                    .project([
                        centre[0] + dx * margin_m,
                        centre[1] + dy * margin_m,
                        centre[2],
                    ])
                    .is_some_and(|(u, v)| intrinsics.contains(u, v))
            });
        if inside {
            return Some(AppleSphere {
                centre_in_camera_m: centre,
                radius_m,
                rgb: [rng.random_range(120..=170), rng.random_range(20..=45), 25],
            });
        }
    }
    None
}

/// The apple, maybe a leaf in front of it, and a canopy plane 40 cm behind.
fn scene_around(apple: AppleSphere, config: &AccuracyConfig, rng: &mut SmallRng) -> AlacsScene {
    let centre = apple.centre_in_camera_m;
    let radius_m = apple.radius_m;
    let mut leaves = Vec::new();
    if rng.random_bool(config.leaf_probability) {
        leaves.push(LeafDisc {
            centre_in_camera_m: [
                centre[0] + rng.random_range(-1.2..=1.2) * radius_m,
                centre[1] + rng.random_range(-1.2..=1.2) * radius_m,
                centre[2] - radius_m - rng.random_range(0.01..=0.05),
            ],
            normal: [
                rng.random_range(-0.3..=0.3),
                rng.random_range(-0.3..=0.3),
                -1.0,
            ],
            radius_m: rng.random_range(0.4..=0.8) * radius_m,
            rgb: [50, 110, 40],
        });
    }
    AlacsScene {
        apples: vec![apple],
        leaves,
        background_depth_m: Some(centre[2] + 0.4),
        ..AlacsScene::default()
    }
}

/// The detector's box around the apple's silhouette, each edge moved by Gaussian noise.
fn noisy_bbox(
    intrinsics: &CameraIntrinsics,
    apple: &AppleSphere,
    sigma_px: f64,
    unit_normal: &Normal<f64>,
    rng: &mut SmallRng,
) -> PixelRoi {
    let centre = apple.centre_in_camera_m;
    let distance = centre.iter().map(|c| c * c).sum::<f64>().sqrt();
    let (u_c, v_c) = intrinsics.project(centre).unwrap_or((0.0, 0.0));
    let radius_px = intrinsics.fx_px * (apple.radius_m / distance).asin().tan();
    let mut edge = |value: f64| {
        (value + sigma_px * unit_normal.sample(rng))
            .round()
            .max(0.0) as usize
    };
    PixelRoi {
        u_min_px: edge(u_c - radius_px),
        v_min_px: edge(v_c - radius_px),
        u_max_px: edge(u_c + radius_px),
        v_max_px: edge(v_c + radius_px),
    }
}

impl std::fmt::Display for AccuracyReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let cell = |errors: &AxisErrors| {
            format!(
                "{:>6.2} {:>6.2} {:>6.2}",
                errors.max_abs_mm[0], errors.max_abs_mm[1], errors.max_abs_mm[2]
            )
        };
        writeln!(
            f,
            "ALACS localisation accuracy, max |error| x y z in mm (paper worst case: {:.1} {:.1} {:.1})",
            self.paper_max_mm[0], self.paper_max_mm[1], self.paper_max_mm[2]
        )?;
        writeln!(
            f,
            "{:>6} {:>7} {:>7} {:>22} {:>22} {:>22} {:>22} {:>6}",
            "d cm",
            "images",
            "points",
            "stripe pts, calibrated",
            "stripe pts, true extr.",
            "3 pts/image (paper)",
            "apple centres",
            "wrong"
        )?;
        for slide in &self.per_slide {
            writeln!(
                f,
                "{:>6.1} {:>3}/{:<3} {:>7} {:>22} {:>22} {:>22} {:>22} {:>6}",
                slide.slide_position_m * 100.0,
                slide.images_with_candidate,
                slide.images,
                slide.points.count,
                cell(&slide.points),
                cell(&slide.points_true_extrinsics),
                cell(&slide.paper_sample),
                cell(&slide.centres),
                slide.misattributed_points
            )?;
        }
        writeln!(
            f,
            "{:>6} {:>7} {:>7} {:>22} {:>22} {:>22} {:>22}",
            "all",
            "",
            self.points.count,
            cell(&self.points),
            cell(&self.points_true_extrinsics),
            cell(&self.paper_sample),
            cell(&self.centres)
        )?;
        writeln!(
            f,
            "mean |error| stripe points (calibrated): {:.2} {:.2} {:.2} mm; apple centres: {:.2} {:.2} {:.2} mm",
            self.points.mean_abs_mm[0],
            self.points.mean_abs_mm[1],
            self.points.mean_abs_mm[2],
            self.centres.mean_abs_mm[0],
            self.centres.mean_abs_mm[1],
            self.centres.mean_abs_mm[2]
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn true_extrinsics_localise_stripe_points_within_the_paper_bounds() {
        // Smaller camera (same field of view) to keep the test quick.
        let mut intrinsics = harvest_hw::alacs::alacs_camera_intrinsics();
        intrinsics.width_px = 720;
        intrinsics.height_px = 540;
        intrinsics.fx_px *= 0.5;
        intrinsics.fy_px *= 0.5;
        intrinsics.cx_px = 359.5;
        intrinsics.cy_px = 269.5;
        let truth = AlacsExtrinsics::paper_table1();
        let config = AccuracyConfig {
            slide_positions_m: vec![0.0, 0.2],
            depths: 3,
            leaf_probability: 0.5,
            ..AccuracyConfig::default()
        };
        let report =
            evaluate_localization_accuracy(intrinsics, &truth, &truth, &config).expect("evaluate");
        assert_eq!(report.per_slide.len(), 2);
        for slide in &report.per_slide {
            assert_eq!(slide.images, 3, "{slide:?}");
            assert_eq!(slide.images_with_candidate, 3, "{slide:?}");
            assert_eq!(slide.misattributed_points, 0, "{slide:?}");
        }
        // With perfect extrinsics only extraction noise remains; at half resolution the
        // depth bound is twice the paper's.
        assert!(report.points.count > 100);
        assert!(report.points.max_abs_mm[2] < 8.0, "{report}");
        assert!(
            report.centres.max_abs_mm.iter().all(|e| *e < 10.0),
            "{report}"
        );
        assert_eq!(report.points, report.points_true_extrinsics);
        // The paper's protocol: 3 points per image, a subset of all the points.
        assert_eq!(report.paper_sample.count, 3 * 6);
        for axis in 0..3 {
            assert!(report.paper_sample.max_abs_mm[axis] <= report.points.max_abs_mm[axis]);
        }
    }
}
