//! Target-based LiDAR-camera extrinsic calibration (LiDAR-camera paper, section II-C-1) and its
//! Table-I-style report.
//!
//! Per view: the checkerboard's inner corners detected in the image (pixels,
//! [`crate::image_corners`]) and in the point cloud ([`crate::cloud_corners`]), matched by their
//! index on the board; then the extrinsic minimizing eq. 3 over all views
//! ([`crate::extrinsic_solver`]) from the CAD transform. A view whose board was not found in
//! either sensor is dropped with its reason (and a warning) while enough views remain.
//!
//! Report (Table I): the average reprojection error (AVG, pixels) of the LiDAR corners projected
//! with the calibrated extrinsic against the image corners (the pseudo ground truth), and the
//! normalized reprojection error (NRE): each view's error multiplied by the ratio of its board
//! distance to the largest board distance, so near boards (large in the image, large errors in
//! pixels) do not dominate. With generated scenes the error against the true extrinsic is
//! reported too, and so is the image corner detector's error against the true projections.

use crate::board_image::BoardImageConfig;
use crate::calibration_scenes::{CalibrationScenes, SceneConfig, SceneError, generate_scenes};
use crate::checkerboard::Checkerboard;
use crate::cloud_corners::{CornerError, detect_board_corners};
use crate::extrinsic_solver::{
    Correspondence, ExtrinsicSolution, SolveError, SolverConfig, residual, rotation_error_rad,
    solve_extrinsic, translation_error_m,
};
use crate::image_corners::ImageCornerError;
use harvest_hw::lidar::LidarSpec;
use harvest_hw::lidar::mounting::{CAD_CAMERA_FROM_LIDAR, simulated_camera_from_lidar};
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::LidarPoint;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// One view's inputs: the image corners and the LiDAR cloud of the board.
#[derive(Debug, Clone, Copy)]
pub struct ViewInput<'a> {
    /// The board's inner corners found in the image, or why they were not.
    pub image_corners_px: Result<&'a [[f64; 2]], &'a ImageCornerError>,
    pub cloud: &'a [LidarPoint],
}

/// What happened to one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    pub index: usize,
    /// Board distance from the LiDAR, metres (0 when the view was dropped).
    pub distance_m: f64,
    pub cloud_points: usize,
    /// Mean reprojection error of this view's corners at the solution, pixels.
    pub mean_error_px: f64,
    /// Why the view was not used, if it was not.
    pub dropped: Option<String>,
}

/// The Table-I-style result.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationReport {
    pub camera_from_lidar: RigidTransform,
    pub solution: ExtrinsicSolution,
    pub views: Vec<ViewReport>,
    pub corners_used: usize,
    /// Average reprojection error, pixels (Table I "AVG").
    pub average_error_px: f64,
    /// Normalized reprojection error, pixels (Table I "NRE").
    pub normalized_error_px: f64,
    /// Image corner detection error against the true projections (generated scenes only).
    pub image_corner_error: Option<ImageCornerAccuracy>,
    /// Errors against the true extrinsic (generated scenes only): `(initial, calibrated)`.
    pub rotation_error_deg: Option<(f64, f64)>,
    pub translation_error_mm: Option<(f64, f64)>,
    pub elapsed_s: f64,
}

/// How far the image corners found lie from the true projections (generated scenes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageCornerAccuracy {
    pub median_px: f64,
    pub max_px: f64,
    /// Corners compared, over `views` views with the board found in the image.
    pub corners: usize,
    pub views: usize,
}

impl ImageCornerAccuracy {
    /// Compares the views' found corners with their true projections, index by index; views
    /// without corners are left out. `None` when no view has corners.
    pub fn measure<'a>(
        views: impl IntoIterator<Item = (&'a [[f64; 2]], &'a [[f64; 2]])>,
    ) -> Option<Self> {
        let mut errors = Vec::new();
        let mut count = 0;
        for (found, truth) in views {
            if found.is_empty() || found.len() != truth.len() {
                continue;
            }
            count += 1;
            errors.extend(
                found
                    .iter()
                    .zip(truth)
                    .map(|(f, t)| (f[0] - t[0]).hypot(f[1] - t[1])),
            );
        }
        errors.sort_by(f64::total_cmp);
        let max_px = *errors.last()?;
        Some(Self {
            median_px: errors[errors.len() / 2],
            max_px,
            corners: errors.len(),
            views: count,
        })
    }
}

/// Why calibration failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    #[error("no view given")]
    NoViews,
    #[error(
        "only {usable} of {total} views gave corners in both sensors, need at least {needed}; \
         dropped: {reasons}"
    )]
    TooFewViews {
        usable: usize,
        total: usize,
        needed: usize,
        reasons: String,
    },
    #[error(transparent)]
    Solve(#[from] SolveError),
    #[error(transparent)]
    Scenes(#[from] SceneError),
}

/// Minimum views with corners in both sensors.
pub const MIN_VIEWS: usize = 3;

/// Calibrates from views; `truth` (generated scenes) adds the error against it to the report.
pub fn calibrate(
    intrinsics: &CameraIntrinsics,
    board: &Checkerboard,
    views: &[ViewInput<'_>],
    initial: &RigidTransform,
    truth: Option<&RigidTransform>,
) -> Result<CalibrationReport, CalibrationError> {
    let started = Instant::now();
    if views.is_empty() {
        return Err(CalibrationError::NoViews);
    }
    let mut reports = Vec::with_capacity(views.len());
    let mut correspondences = Vec::new();
    let mut view_of = Vec::new();
    for (index, view) in views.iter().enumerate() {
        let mut report = ViewReport {
            index,
            distance_m: 0.0,
            cloud_points: view.cloud.len(),
            mean_error_px: f64::NAN,
            dropped: None,
        };
        let image_corners_px = match view.image_corners_px {
            Ok(corners) => corners,
            Err(error) => {
                tracing::warn!(view = index, %error, "no board corners in the image");
                report.dropped = Some(error.to_string());
                reports.push(report);
                continue;
            }
        };
        if image_corners_px.len() != board.corner_count() {
            report.dropped = Some(format!(
                "{} image corners, the board has {}",
                image_corners_px.len(),
                board.corner_count()
            ));
            tracing::warn!(view = index, reason = ?report.dropped, "view dropped");
            reports.push(report);
            continue;
        }
        match detect_board_corners(view.cloud, board) {
            Ok(detection) => {
                report.distance_m = detection.distance_m;
                for (point, pixel) in detection.corners_in_lidar_m.iter().zip(image_corners_px) {
                    correspondences.push(Correspondence {
                        point_in_lidar_m: *point,
                        pixel: *pixel,
                    });
                    view_of.push(index);
                }
            }
            Err(error) => {
                let error: CornerError = error;
                tracing::warn!(view = index, %error, "no board corners in the cloud");
                report.dropped = Some(error.to_string());
            }
        }
        reports.push(report);
    }
    let usable = reports.iter().filter(|r| r.dropped.is_none()).count();
    if usable < MIN_VIEWS {
        let reasons = reports
            .iter()
            .filter_map(|r| r.dropped.as_ref().map(|d| format!("view {}: {d}", r.index)))
            .collect::<Vec<_>>()
            .join("; ");
        return Err(CalibrationError::TooFewViews {
            usable,
            total: views.len(),
            needed: MIN_VIEWS,
            reasons,
        });
    }
    let config = SolverConfig::default();
    let mut solution = solve_extrinsic(intrinsics, &correspondences, initial, &config)?;
    // A view whose corners disagree with all the others (a template locked one square off, a
    // mismatched image) drags a least-squares solution, so it does not stand out by its own
    // residual. Each view is left out in turn: leaving out the bad one makes the rest fit far
    // better than leaving out any good one. That view is dropped (repeatedly, while one stands
    // out and enough views remain) and the extrinsic solved again.
    let mut remaining = usable;
    while remaining > MIN_VIEWS {
        let left_out = leave_one_out(
            intrinsics,
            &correspondences,
            &view_of,
            views.len(),
            initial,
            &config,
        );
        let mut fits: Vec<f64> = left_out.iter().flatten().map(|l| l.others_rms_px).collect();
        if fits.len() <= MIN_VIEWS {
            break;
        }
        fits.sort_by(f64::total_cmp);
        let median = fits[fits.len() / 2];
        let Some((view, worst)) = left_out
            .iter()
            .enumerate()
            .filter_map(|(v, l)| l.map(|l| (v, l)))
            .min_by(|a, b| a.1.others_rms_px.total_cmp(&b.1.others_rms_px))
        else {
            break;
        };
        if !(worst.others_rms_px < 0.5 * median && worst.predicted_px > OUTLIER_VIEW_MIN_PX) {
            break;
        }
        tracing::warn!(
            view,
            predicted_px = worst.predicted_px,
            others_rms_px = worst.others_rms_px,
            median_rms_px = median,
            "inconsistent view dropped"
        );
        reports[view].dropped = Some(format!(
            "corners inconsistent with the other views (predicted {:.2} px off by their \
             extrinsic; without it the rest fit to {:.2} px RMS instead of {median:.2})",
            worst.predicted_px, worst.others_rms_px
        ));
        let keep: Vec<bool> = view_of.iter().map(|v| *v != view).collect();
        let mut flags = keep.iter();
        correspondences.retain(|_| flags.next().copied().unwrap_or(false));
        let mut flags = keep.iter();
        view_of.retain(|_| flags.next().copied().unwrap_or(false));
        solution = solve_extrinsic(intrinsics, &correspondences, initial, &config)?;
        remaining -= 1;
    }
    let transform = solution.camera_from_lidar;
    // Table I: per-corner errors, and per view for the distance normalization.
    let max_distance = reports
        .iter()
        .filter(|r| r.dropped.is_none())
        .map(|r| r.distance_m)
        .fold(0.0, f64::max);
    let (mut sum, mut sum_normalized) = (0.0, 0.0);
    for (c, &view) in correspondences.iter().zip(&view_of) {
        let error =
            residual(intrinsics, &transform, c).map_or(f64::INFINITY, |[du, dv]| du.hypot(dv));
        sum += error;
        sum_normalized += error * reports[view].distance_m / max_distance;
    }
    let per_view = view_errors(
        intrinsics,
        &transform,
        &correspondences,
        &view_of,
        views.len(),
    );
    for (report, error) in reports.iter_mut().zip(per_view) {
        if let Some(error) = error {
            report.mean_error_px = error;
        }
    }
    let n = correspondences.len() as f64;
    let errors = truth.map(|truth| {
        (
            (
                rotation_error_rad(initial, truth).to_degrees(),
                rotation_error_rad(&transform, truth).to_degrees(),
            ),
            (
                translation_error_m(initial, truth) * 1e3,
                translation_error_m(&transform, truth) * 1e3,
            ),
        )
    });
    Ok(CalibrationReport {
        camera_from_lidar: transform,
        solution,
        views: reports,
        corners_used: correspondences.len(),
        average_error_px: sum / n,
        normalized_error_px: sum_normalized / n,
        image_corner_error: None,
        rotation_error_deg: errors.map(|e| e.0),
        translation_error_mm: errors.map(|e| e.1),
        elapsed_s: started.elapsed().as_secs_f64(),
    })
}

/// A view is inconsistent when its mean error exceeds three times the median view's and this.
const OUTLIER_VIEW_MIN_PX: f64 = 2.0;

/// One view left out of the solve.
#[derive(Debug, Clone, Copy)]
struct LeftOut {
    /// Mean error of the view's corners under the extrinsic of the other views, pixels.
    predicted_px: f64,
    /// RMS reprojection error of the other views' corners at their own solution, pixels.
    others_rms_px: f64,
}

/// Solves without each view in turn (`None` for views without corners or failed solves).
fn leave_one_out(
    intrinsics: &CameraIntrinsics,
    correspondences: &[Correspondence],
    view_of: &[usize],
    views: usize,
    initial: &RigidTransform,
    config: &SolverConfig,
) -> Vec<Option<LeftOut>> {
    let mut results = vec![None; views];
    let mut others = Vec::with_capacity(correspondences.len());
    for (left_out, result) in results.iter_mut().enumerate() {
        if !view_of.contains(&left_out) {
            continue;
        }
        others.clear();
        others.extend(
            correspondences
                .iter()
                .zip(view_of)
                .filter(|(_, v)| **v != left_out)
                .map(|(c, _)| *c),
        );
        let Ok(solution) = solve_extrinsic(intrinsics, &others, initial, config) else {
            continue;
        };
        let errors = view_errors(
            intrinsics,
            &solution.camera_from_lidar,
            correspondences,
            view_of,
            views,
        );
        *result = errors[left_out].map(|predicted_px| LeftOut {
            predicted_px,
            others_rms_px: solution.final_rms_px,
        });
    }
    results
}

/// Mean reprojection error of each view's corners (`None` for views without corners), pixels.
fn view_errors(
    intrinsics: &CameraIntrinsics,
    camera_from_lidar: &RigidTransform,
    correspondences: &[Correspondence],
    view_of: &[usize],
    views: usize,
) -> Vec<Option<f64>> {
    let mut sums = vec![(0.0, 0usize); views];
    for (c, &view) in correspondences.iter().zip(view_of) {
        let error = residual(intrinsics, camera_from_lidar, c)
            .map_or(f64::INFINITY, |[du, dv]| du.hypot(dv));
        sums[view].0 += error;
        sums[view].1 += 1;
    }
    sums.into_iter()
        .map(|(sum, count)| (count > 0).then(|| sum / count as f64))
        .collect()
}

/// Calibrates from generated scenes, with their true extrinsic as the reference.
pub fn calibrate_scenes(
    scenes: &CalibrationScenes,
    initial: &RigidTransform,
) -> Result<CalibrationReport, CalibrationError> {
    let inputs: Vec<ViewInput<'_>> = scenes
        .views
        .iter()
        .map(|view| ViewInput {
            image_corners_px: view.image_corners_px.as_deref(),
            cloud: &view.cloud,
        })
        .collect();
    let mut report = calibrate(
        &scenes.intrinsics,
        &scenes.board,
        &inputs,
        initial,
        Some(&scenes.true_camera_from_lidar),
    )?;
    report.image_corner_error =
        ImageCornerAccuracy::measure(scenes.views.iter().filter_map(|view| {
            view.image_corners_px
                .as_deref()
                .ok()
                .map(|found| (found, view.true_image_corners_px.as_slice()))
        }));
    Ok(report)
}

impl CalibrationReport {
    /// The Table-I-style text report.
    pub fn render(&self) -> String {
        let mut text = String::new();
        let used = self.views.iter().filter(|v| v.dropped.is_none()).count();
        let _ = writeln!(
            text,
            "LiDAR-camera extrinsic calibration (target-based, eq. 3), {used} of {} views, {} \
             corners, {} LM iterations, {:.2} s",
            self.views.len(),
            self.corners_used,
            self.solution.iterations,
            self.elapsed_s
        );
        let _ = writeln!(text, "\nview  distance_m  cloud_points  mean_error_px");
        for view in &self.views {
            match &view.dropped {
                None => {
                    let _ = writeln!(
                        text,
                        "{:>4}  {:>10.2}  {:>12}  {:>13.2}",
                        view.index, view.distance_m, view.cloud_points, view.mean_error_px
                    );
                }
                Some(reason) => {
                    let _ = writeln!(text, "{:>4}  dropped: {reason}", view.index);
                }
            }
        }
        let _ = writeln!(text, "\nTable I (reprojection error)");
        let _ = writeln!(text, "method                      AVG/pixel  NRE/pixel");
        let _ = writeln!(
            text,
            "target-based (this run)     {:>9.2}  {:>9.2}",
            self.average_error_px, self.normalized_error_px
        );
        let _ = writeln!(text, "target-based (paper)             2.03       0.78");
        let _ = writeln!(text, "target-less  (paper)             1.91       0.66");
        let _ = writeln!(
            text,
            "\nRMS reprojection: {:.2} px at the CAD guess -> {:.2} px calibrated; condition {:.1e}",
            self.solution.initial_rms_px, self.solution.final_rms_px, self.solution.condition
        );
        if let Some(accuracy) = &self.image_corner_error {
            let _ = writeln!(
                text,
                "image corners found vs true projections: median {:.3} px, max {:.3} px ({} \
                 corners in {} views)",
                accuracy.median_px, accuracy.max_px, accuracy.corners, accuracy.views
            );
        }
        if let (Some((r0, r1)), Some((t0, t1))) =
            (self.rotation_error_deg, self.translation_error_mm)
        {
            let _ = writeln!(
                text,
                "error vs the true extrinsic: rotation {r0:.3} deg -> {r1:.3} deg, translation \
                 {t0:.2} mm -> {t1:.2} mm (CAD guess -> calibrated)"
            );
        }
        let t = &self.camera_from_lidar;
        let _ = writeln!(
            text,
            "camera_from_lidar: rotation {:?}, translation_m [{:.4}, {:.4}, {:.4}]",
            t.rotation.map(|row| row.map(|v| (v * 1e6).round() / 1e6)),
            t.translation_m[0],
            t.translation_m[1],
            t.translation_m[2]
        );
        text
    }
}

/// `harvest calibrate lidar-camera`.
#[derive(Debug, Clone, clap::Args)]
pub struct CalibrateLidarCameraArgs {
    /// Board placements in the generated data set.
    #[arg(long, default_value_t = 12)]
    pub views: usize,
    /// LiDAR integration per placement, seconds (the paper uses 15 s).
    #[arg(long, default_value_t = 15.0)]
    pub integration_s: f64,
    /// Sensor noise of the rendered camera images (one sigma), grey levels of 255.
    #[arg(long, default_value_t = 2.0)]
    pub image_noise_grey: f64,
    /// Seed of the generated data set.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the calibrated `camera_from_lidar` to this TOML file.
    #[arg(long)]
    pub output: Option<PathBuf>,
}

/// Errors of the calibrate command.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateCommandError {
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("encoding the extrinsic as TOML: {0}")]
    Encode(#[from] toml::ser::Error),
}

/// The extrinsic file written by `--output`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtrinsicFile {
    pub camera_from_lidar: RigidTransform,
    pub average_error_px: f64,
    pub normalized_error_px: f64,
}

/// Why an extrinsic file cannot be used (file, line and key named).
pub type ReadExtrinsicError = harvest_ipc::config_file::ConfigFileError;

impl ExtrinsicFile {
    /// Reads a file written by `harvest calibrate lidar-camera --output`.
    pub fn read(path: &std::path::Path) -> Result<Self, ReadExtrinsicError> {
        harvest_ipc::config_file::read_toml(path, "LiDAR extrinsic")
    }
}

/// Generates scenes from the simulated unit's extrinsic, calibrates from the CAD guess, prints
/// the report, optionally writes the extrinsic.
pub fn run_calibrate_lidar_camera(
    args: &CalibrateLidarCameraArgs,
) -> Result<CalibrationReport, CalibrateCommandError> {
    let config = SceneConfig {
        views: args.views,
        integration_s: args.integration_s,
        image: BoardImageConfig {
            noise_grey: args.image_noise_grey,
            ..BoardImageConfig::default()
        },
        seed: args.seed,
        ..SceneConfig::default()
    };
    let scenes = generate_scenes(
        &config,
        CameraIntrinsics::tl460_rgb(),
        &LidarSpec::mid70(),
        Checkerboard::paper(),
        simulated_camera_from_lidar(),
    )
    .map_err(CalibrationError::from)?;
    let report = calibrate_scenes(&scenes, &CAD_CAMERA_FROM_LIDAR)?;
    print!("{}", report.render());
    if let Some(path) = &args.output {
        let file = ExtrinsicFile {
            camera_from_lidar: report.camera_from_lidar,
            average_error_px: report.average_error_px,
            normalized_error_px: report.normalized_error_px,
        };
        let text = toml::to_string(&file)?;
        std::fs::write(path, text).map_err(|source| CalibrateCommandError::Write {
            path: path.clone(),
            source,
        })?;
        println!("extrinsic written to {}", path.display());
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board_image::GreyImage;
    use crate::image_corners::{ImageCornerConfig, detect_image_corners};

    fn scenes(views: usize, integration_s: f64, seed: u64) -> CalibrationScenes {
        let config = SceneConfig {
            views,
            integration_s,
            seed,
            ..SceneConfig::default()
        };
        generate_scenes(
            &config,
            CameraIntrinsics::tl460_rgb(),
            &LidarSpec::mid70(),
            Checkerboard::paper(),
            simulated_camera_from_lidar(),
        )
        .expect("scenes")
    }

    #[test]
    fn cloud_corners_match_the_true_board_corners() {
        let scenes = scenes(3, 2.0, 5);
        let lidar_from_camera = scenes.true_camera_from_lidar.inverse();
        for view in &scenes.views {
            let detection = detect_board_corners(&view.cloud, &scenes.board).expect("corners");
            let mut worst: f64 = 0.0;
            for (found, [x, y]) in detection
                .corners_in_lidar_m
                .iter()
                .zip(scenes.board.corners_m())
            {
                let truth = lidar_from_camera.apply(view.camera_from_board.apply([x, y, 0.0]));
                let error = (0..3)
                    .map(|k| (found[k] - truth[k]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                worst = worst.max(error);
            }
            assert!(worst < 0.003, "worst corner error {worst} m");
            assert!(detection.template_agreement > 0.9);
        }
    }

    #[test]
    fn recovers_a_known_extrinsic_within_half_a_degree_and_5_mm() {
        for seed in [1, 2] {
            let scenes = scenes(8, 2.0, seed);
            let report = calibrate_scenes(&scenes, &CAD_CAMERA_FROM_LIDAR).expect("calibrate");
            let (initial_deg, final_deg) = report.rotation_error_deg.expect("truth");
            let (initial_mm, final_mm) = report.translation_error_mm.expect("truth");
            assert!(
                initial_deg > 0.8 && initial_mm > 5.0,
                "the CAD guess is off"
            );
            assert!(final_deg < 0.5, "rotation error {final_deg} deg");
            assert!(final_mm < 5.0, "translation error {final_mm} mm");
            assert!(
                report.views.iter().all(|v| v.dropped.is_none()),
                "{}",
                report.render()
            );
            assert!(report.normalized_error_px <= report.average_error_px);
            assert!(report.average_error_px < 3.0, "{}", report.render());
            assert!(report.render().contains("AVG/pixel"));
            // Every view's corners were found in its rendered image, close to the truth.
            let accuracy = report.image_corner_error.expect("generated scenes");
            assert_eq!((accuracy.views, accuracy.corners), (8, 8 * 35));
            assert!(accuracy.median_px < 0.3, "{}", report.render());
            assert!(accuracy.max_px < 1.0, "{}", report.render());
            assert!(
                report
                    .render()
                    .contains("image corners found vs true projections")
            );
        }
    }

    #[test]
    fn a_view_without_the_board_in_its_image_is_dropped_by_name() {
        let mut scenes = scenes(4, 2.0, 9);
        let blank = GreyImage::filled(1920, 1080, 128);
        scenes.views[1].image_corners_px =
            detect_image_corners(&blank, &scenes.board, &ImageCornerConfig::default())
                .map(|found| found.corners_px);
        let report = calibrate_scenes(&scenes, &CAD_CAMERA_FROM_LIDAR).expect("calibrate");
        let reason = report.views[1].dropped.as_deref().expect("view 1 dropped");
        assert!(reason.contains("0 corner candidates"), "{reason}");
        assert_eq!(
            report.views.iter().filter(|v| v.dropped.is_none()).count(),
            3
        );
        let accuracy = report.image_corner_error.expect("generated scenes");
        assert_eq!(accuracy.views, 3);
        let (_, final_deg) = report.rotation_error_deg.expect("truth");
        assert!(final_deg < 0.5, "{}", report.render());
        // With only two views left the calibration is refused, naming the view.
        scenes.views[2].image_corners_px = scenes.views[1].image_corners_px.clone();
        let error = calibrate_scenes(&scenes, &CAD_CAMERA_FROM_LIDAR).expect_err("two views");
        assert!(
            error
                .to_string()
                .contains("view 1: only 0 corner candidates"),
            "{error}"
        );
    }

    #[test]
    fn a_view_with_mismatched_corners_is_dropped_and_the_rest_calibrate() {
        let mut scenes = scenes(6, 2.0, 7);
        for pixel in scenes.views[2]
            .image_corners_px
            .as_mut()
            .expect("board found in the image")
        {
            pixel[0] += 12.0;
        }
        let report = calibrate_scenes(&scenes, &CAD_CAMERA_FROM_LIDAR).expect("calibrate");
        let dropped: Vec<usize> = report
            .views
            .iter()
            .filter(|v| v.dropped.is_some())
            .map(|v| v.index)
            .collect();
        assert_eq!(dropped, vec![2], "{}", report.render());
        let (_, final_deg) = report.rotation_error_deg.expect("truth");
        let (_, final_mm) = report.translation_error_mm.expect("truth");
        assert!(final_deg < 0.5 && final_mm < 5.0, "{}", report.render());
    }

    #[test]
    fn degenerate_calibrations_are_refused_with_reasons() {
        let scenes = scenes(3, 1.0, 3);
        let board = scenes.board;
        let k = scenes.intrinsics;
        // Views whose clouds are empty: too few usable views, each reason named.
        let empty: Vec<ViewInput<'_>> = scenes
            .views
            .iter()
            .map(|v| ViewInput {
                image_corners_px: v.image_corners_px.as_deref(),
                cloud: &[],
            })
            .collect();
        let error = calibrate(&k, &board, &empty, &CAD_CAMERA_FROM_LIDAR, None).expect_err("empty");
        assert!(matches!(
            error,
            CalibrationError::TooFewViews { usable: 0, .. }
        ));
        assert!(
            error.to_string().contains("view 0: only 0 finite points"),
            "{error}"
        );
        // The same placement three times: every corner on one plane.
        let same: Vec<ViewInput<'_>> = (0..3)
            .map(|_| ViewInput {
                image_corners_px: scenes.views[0].image_corners_px.as_deref(),
                cloud: &scenes.views[0].cloud,
            })
            .collect();
        let error = calibrate(&k, &board, &same, &CAD_CAMERA_FROM_LIDAR, None).expect_err("flat");
        assert!(
            matches!(error, CalibrationError::Solve(SolveError::Coplanar { .. })),
            "{error}"
        );
        assert!(matches!(
            calibrate(&k, &board, &[], &CAD_CAMERA_FROM_LIDAR, None),
            Err(CalibrationError::NoViews)
        ));
        let bad = SceneConfig {
            max_tilt_deg: -1.0,
            ..SceneConfig::default()
        };
        let error = generate_scenes(&bad, k, &LidarSpec::mid70(), board, CAD_CAMERA_FROM_LIDAR)
            .expect_err("negative tilt");
        assert!(error.to_string().contains("max_tilt_deg = -1"), "{error}");
    }
}
