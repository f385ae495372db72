//! Target-based LiDAR-camera extrinsic calibration ([fusion sec. II-C-1]) and its
//! Table-I-style report.
//!
//! Per view: the checkerboard's inner corners detected in the image (pixels,
//! [`crate::lidar::image_corners`]) and in the point cloud ([`crate::lidar::cloud_corners`]), matched by their
//! index on the board; then the extrinsic minimizing eq. 3 over all views
//! ([`crate::lidar::extrinsic_solver`]) from the CAD transform. A view whose board was not found in
//! either sensor is dropped with its reason (and a warning) while enough views remain.
//!
//! Report (Table I): the average reprojection error (AVG, pixels) of the LiDAR corners projected
//! with the calibrated extrinsic against the image corners (the pseudo ground truth), and the
//! normalized reprojection error (NRE): each view's error multiplied by the ratio of its board
//! distance to the largest board distance, so near boards (large in the image, large errors in
//! pixels) do not dominate. With generated scenes the error against the true extrinsic is
//! reported too, and so is the image corner detector's error against the true projections.
//!
//! The views come from generated scenes ([`calibrate_scenes`]) or from a recorded data-set
//! directory ([`calibrate_data_set`], format in [`crate::lidar::calibration_data`]); both feed the same
//! [`calibrate`], so the solve, the outlier-view rejection and the report are one code path.

use crate::lidar::board_image::BoardImageConfig;
use crate::lidar::calibration_data::{
    CameraFile, DataSet, DataSetError, view_name, write_data_set,
};
use crate::lidar::calibration_scenes::{
    CalibrationScenes, SceneConfig, SceneError, generate_scenes,
};
use crate::lidar::checkerboard::Checkerboard;
use crate::lidar::cloud_corners::{CornerError, detect_board_corners};
use crate::lidar::extrinsic_solver::{
    Correspondence, ExtrinsicSolution, SolveError, SolverConfig, residual, rotation_error_rad,
    solve_extrinsic, translation_error_m,
};
use crate::lidar::image_corners::{ImageCornerConfig, ImageCornerError, detect_image_corners};
use harvest_hw::lidar::LidarSpec;
use harvest_hw::lidar::mounting::CAD_CAMERA_FROM_LIDAR;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::LidarPoint;
use harvest_lidar::extrinsic_file::{ExtrinsicFile, ReadExtrinsicError};
use harvest_sim::lidar_device::simulated_camera_from_lidar;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

/// One view's inputs: the image corners and the LiDAR cloud of the board.
#[derive(Debug, Clone, Copy)]
pub struct ViewInput<'a> {
    /// The view's name in warnings and the report (the data set's file stem, `00`, `01`, ...).
    pub name: &'a str,
    /// The board's inner corners found in the image, or why they were not.
    pub image_corners_px: Result<&'a [[f64; 2]], &'a ImageCornerError>,
    pub cloud: &'a [LidarPoint],
}

/// What happened to one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// Position among the views given.
    pub index: usize,
    /// The view's name (file stem).
    pub name: String,
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
    /// The solve started from the CAD guess (else from a given extrinsic): report wording.
    pub initial_is_cad: bool,
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
            name: view.name.to_owned(),
            distance_m: 0.0,
            cloud_points: view.cloud.len(),
            mean_error_px: f64::NAN,
            dropped: None,
        };
        let image_corners_px = match view.image_corners_px {
            Ok(corners) => corners,
            Err(error) => {
                tracing::warn!(view = view.name, %error, "no board corners in the image, dropped");
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
            tracing::warn!(view = view.name, reason = ?report.dropped, "view dropped");
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
                tracing::warn!(view = view.name, %error, "no board corners in the cloud, dropped");
                report.dropped = Some(error.to_string());
            }
        }
        reports.push(report);
    }
    let usable = reports.iter().filter(|r| r.dropped.is_none()).count();
    if usable < MIN_VIEWS {
        let reasons = reports
            .iter()
            .filter_map(|r| r.dropped.as_ref().map(|d| format!("view {}: {d}", r.name)))
            .collect::<Vec<_>>()
            .join("; ");
        let reasons = if reasons.is_empty() {
            "none (too few views given)".to_owned()
        } else {
            reasons
        };
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
            view = views[view].name,
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
        initial_is_cad: *initial == CAD_CAMERA_FROM_LIDAR,
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
    let names: Vec<String> = (0..scenes.views.len()).map(view_name).collect();
    let inputs: Vec<ViewInput<'_>> = scenes
        .views
        .iter()
        .zip(&names)
        .map(|(view, name)| ViewInput {
            name,
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

/// Calibrates from a data-set directory ([`crate::lidar::calibration_data`]): per view the image is
/// read and its corners found (the image is then dropped), the cloud is read, and the views go
/// through [`calibrate`] like generated ones, without a true extrinsic. A view whose board is not
/// found is dropped with its reason; a file that cannot be read is an error naming it.
pub fn calibrate_data_set(
    data: &DataSet,
    initial: &RigidTransform,
) -> Result<CalibrationReport, CalibrateCommandError> {
    let detector = ImageCornerConfig::default();
    let mut loaded = Vec::with_capacity(data.views.len());
    for view in &data.views {
        let image = data.read_image(view)?;
        let corners =
            detect_image_corners(&image, &data.board, &detector).map(|found| found.corners_px);
        drop(image);
        let cloud = data.read_cloud(view)?;
        tracing::debug!(
            view = view.name,
            points = cloud.len(),
            image_corners = corners.as_ref().map_or(0, Vec::len),
            "view loaded"
        );
        loaded.push((corners, cloud));
    }
    let inputs: Vec<ViewInput<'_>> = data
        .views
        .iter()
        .zip(&loaded)
        .map(|(view, (corners, cloud))| ViewInput {
            name: &view.name,
            image_corners_px: corners.as_deref(),
            cloud,
        })
        .collect();
    Ok(calibrate(
        &data.intrinsics,
        &data.board,
        &inputs,
        initial,
        None,
    )?)
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
                        view.name, view.distance_m, view.cloud_points, view.mean_error_px
                    );
                }
                Some(reason) => {
                    let _ = writeln!(text, "{:>4}  dropped: {reason}", view.name);
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
        let initial = if self.initial_is_cad {
            "the CAD guess"
        } else {
            "the initial extrinsic"
        };
        let _ = writeln!(
            text,
            "\nRMS reprojection: {:.2} px at {initial} -> {:.2} px calibrated; condition {:.1e}",
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
                 {t0:.2} mm -> {t1:.2} mm ({} -> calibrated)",
                initial.trim_start_matches("the ")
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

/// `harvest calibrate lidar-camera`: from generated checkerboard scenes (the simulated unit's
/// extrinsic is the truth the report compares against), or with `--data DIR` from a recorded
/// data set ([`crate::lidar::calibration_data`], described in `--help` by [`DATA_SET_HELP`]).
#[derive(Debug, Clone, clap::Args)]
#[command(after_long_help = DATA_SET_HELP)]
pub struct CalibrateLidarCameraArgs {
    /// Calibrate from this data-set directory (camera.toml, NN.png + NN.csv per view) instead of
    /// generated scenes.
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Start from this extrinsic (a file written by --output) instead of the CAD guess.
    #[arg(long, value_name = "FILE")]
    pub initial_extrinsic: Option<PathBuf>,
    /// Also write the generated scenes as a data set (camera.toml, NN.png, NN.csv) to this
    /// directory.
    #[arg(long, value_name = "DIR", conflicts_with = "data")]
    pub write_generated: Option<PathBuf>,
    /// Board placements in the generated data set.
    #[arg(long, default_value_t = Self::DEFAULT.views, conflicts_with = "data")]
    pub views: usize,
    /// LiDAR integration per placement, seconds (the paper uses 15 s; generated data set).
    #[arg(long, default_value_t = Self::DEFAULT.integration_s, conflicts_with = "data")]
    pub integration_s: f64,
    /// Sensor noise of the rendered camera images (one sigma), grey levels of 255.
    #[arg(long, default_value_t = Self::DEFAULT.image_noise_grey, conflicts_with = "data")]
    pub image_noise_grey: f64,
    /// Seed of the generated data set.
    #[arg(long, default_value_t = Self::DEFAULT.seed, conflicts_with = "data")]
    pub seed: u64,
    /// Write the calibrated `camera_from_lidar` to this TOML file.
    #[arg(long, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

impl CalibrateLidarCameraArgs {
    /// The command-line defaults: generated scenes, no files.
    pub const DEFAULT: Self = Self {
        data: None,
        initial_extrinsic: None,
        write_generated: None,
        views: 12,
        integration_s: 15.0,
        image_noise_grey: 2.0,
        seed: 1,
        output: None,
    };
}

/// The data-set format as `--help` states it (after the options; the subcommand's one-line
/// description comes from the CLI).
pub const DATA_SET_HELP: &str = "\
Data set (--data DIR, written by --write-generated DIR):
  DIR/camera.toml  the colour camera and the checkerboard:
                     [intrinsics]  width_px, height_px, fx_px, fy_px, cx_px, cy_px,
                                   distortion = [k1, k2, p1, p2, k3]
                     [board]       optional, default the paper's 7 x 5 inner corners of 5 cm:
                                   inner_columns, inner_rows, square_m, border_m
  DIR/NN.png       per view, the camera image of the board: 8-bit grey or RGB (converted
                   to grey); the size camera.toml states
  DIR/NN.csv       per view, the LiDAR points of the integration window, LiDAR frame: the
                   header x_m,y_m,z_m,intensity then one point per line (metres, 0-255)
A view is a stem NN present as both NN.png and NN.csv. Views whose board is not found in
the image or the cloud are dropped with a warning; at least 3 must remain.";

/// Errors of the calibrate command.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateCommandError {
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// The data set cannot be read (or the generated one written).
    #[error(transparent)]
    Data(#[from] DataSetError),
    /// The `--initial-extrinsic` file cannot be read.
    #[error("initial extrinsic: {0}")]
    InitialExtrinsic(#[from] ReadExtrinsicError),
    /// The `--initial-extrinsic` file holds no rigid transform.
    #[error("initial extrinsic {path}: {reason}")]
    InvalidInitialExtrinsic { path: PathBuf, reason: String },
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("encoding the extrinsic as TOML: {0}")]
    Encode(#[from] toml::ser::Error),
}

/// Reads `--initial-extrinsic` and checks it is a rigid transform (finite, rotation orthonormal
/// within 1e-6).
fn read_initial_extrinsic(path: &std::path::Path) -> Result<RigidTransform, CalibrateCommandError> {
    let transform = ExtrinsicFile::read(path)?.camera_from_lidar;
    if !transform.is_rigid() {
        return Err(CalibrateCommandError::InvalidInitialExtrinsic {
            path: path.to_owned(),
            reason: format!(
                "camera_from_lidar.rotation = {:?} is not a finite proper rotation",
                transform.rotation
            ),
        });
    }
    Ok(transform)
}

/// Calibrates from the data set of `--data`, or from generated scenes (from the simulated unit's
/// extrinsic, optionally written with `--write-generated`); starts from the CAD guess or
/// `--initial-extrinsic`; prints the report and optionally writes the extrinsic.
pub fn run_calibrate_lidar_camera(
    args: &CalibrateLidarCameraArgs,
) -> Result<CalibrationReport, CalibrateCommandError> {
    let initial = match &args.initial_extrinsic {
        Some(path) => read_initial_extrinsic(path)?,
        None => CAD_CAMERA_FROM_LIDAR,
    };
    let report = match &args.data {
        Some(dir) => {
            let data = DataSet::open(dir)?;
            println!(
                "data set {}: {} views, camera {} x {} px, board {} x {} inner corners",
                dir.display(),
                data.views.len(),
                data.intrinsics.width_px,
                data.intrinsics.height_px,
                data.board.inner_columns,
                data.board.inner_rows
            );
            calibrate_data_set(&data, &initial)?
        }
        None => {
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
            if let Some(dir) = &args.write_generated {
                write_scenes(dir, &scenes)?;
                println!(
                    "generated data set written to {} ({} views)",
                    dir.display(),
                    scenes.views.len()
                );
            }
            calibrate_scenes(&scenes, &initial)?
        }
    };
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

/// Writes generated scenes as a data set ([`crate::lidar::calibration_data`]), views named like
/// [`calibrate_scenes`] names them.
pub fn write_scenes(dir: &std::path::Path, scenes: &CalibrationScenes) -> Result<(), DataSetError> {
    let camera = CameraFile {
        intrinsics: scenes.intrinsics,
        board: scenes.board,
    };
    write_data_set(
        dir,
        &camera,
        scenes
            .views
            .iter()
            .enumerate()
            .map(|(index, view)| (view_name(index), &view.image, view.cloud.as_slice())),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lidar::board_image::GreyImage;
    use crate::lidar::calibration_data::{temp_dir, write_png_grey};

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
                .contains("view 01: only 0 corner candidates"),
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
                name: "empty",
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
            error
                .to_string()
                .contains("view empty: only 0 finite points"),
            "{error}"
        );
        // Two good views only: too few, and the message says none was dropped.
        let two: Vec<ViewInput<'_>> = scenes.views[..2]
            .iter()
            .map(|v| ViewInput {
                name: "good",
                image_corners_px: v.image_corners_px.as_deref(),
                cloud: &v.cloud,
            })
            .collect();
        let error = calibrate(&k, &board, &two, &CAD_CAMERA_FROM_LIDAR, None).expect_err("two");
        assert!(
            error.to_string().contains(
                "only 2 of 2 views gave corners in both sensors, need at least 3; dropped: none"
            ),
            "{error}"
        );
        // The same placement three times: every corner on one plane.
        let same: Vec<ViewInput<'_>> = (0..3)
            .map(|_| ViewInput {
                name: "same",
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

    #[test]
    fn a_written_data_set_calibrates_like_the_generated_scenes() {
        let scenes = scenes(6, 2.0, 4);
        let generated = calibrate_scenes(&scenes, &CAD_CAMERA_FROM_LIDAR).expect("generated");
        let dir = temp_dir("round-trip");
        write_scenes(&dir, &scenes).expect("write");
        let data = DataSet::open(&dir).expect("open");
        assert_eq!(data.views.len(), 6);
        assert_eq!(data.intrinsics, scenes.intrinsics);
        let report = calibrate_data_set(&data, &CAD_CAMERA_FROM_LIDAR).expect("data set");
        // Same extrinsic as in memory: lossless PNG and CSV, the same detector and solver.
        let (a, b) = (&report.camera_from_lidar, &generated.camera_from_lidar);
        assert!(
            rotation_error_rad(a, b) < 1e-6 && translation_error_m(a, b) < 1e-6,
            "{}\n{}",
            report.render(),
            generated.render()
        );
        assert_eq!(report.corners_used, generated.corners_used);
        assert!((report.average_error_px - generated.average_error_px).abs() < 1e-6);
        let names: Vec<&str> = report.views.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["00", "01", "02", "03", "04", "05"]);
        // Close to the truth the scenes were generated with.
        let truth = &scenes.true_camera_from_lidar;
        assert!(rotation_error_rad(a, truth).to_degrees() < 0.5);
        assert!(translation_error_m(a, truth) * 1e3 < 5.0);
        // The recorded-data report has no lines that need the truth.
        let text = report.render();
        assert!(report.rotation_error_deg.is_none() && report.image_corner_error.is_none());
        assert!(
            text.contains("AVG/pixel") && text.contains("camera_from_lidar"),
            "{text}"
        );
        assert!(!text.contains("true extrinsic") && !text.contains("true projections"));
        assert!(generated.render().contains("error vs the true extrinsic"));

        // A view whose image shows no board is dropped by name; the rest still calibrate.
        let blank = GreyImage::filled(1920, 1080, 128);
        write_png_grey(&dir.join("03.png"), &blank).expect("blank");
        let report = calibrate_data_set(&data, &CAD_CAMERA_FROM_LIDAR).expect("five views");
        let dropped: Vec<&str> = report
            .views
            .iter()
            .filter(|v| v.dropped.is_some())
            .map(|v| v.name.as_str())
            .collect();
        assert_eq!(dropped, ["03"]);
        assert!(
            report
                .render()
                .contains("  03  dropped: only 0 corner candidates")
        );
        // Fewer usable views than needed: refused, each dropped view named with its reason.
        for name in ["00", "01", "02"] {
            write_png_grey(&dir.join(format!("{name}.png")), &blank).expect("blank");
        }
        let error = calibrate_data_set(&data, &CAD_CAMERA_FROM_LIDAR)
            .expect_err("two usable views")
            .to_string();
        assert!(
            error.contains("only 2 of 6 views")
                && error.contains("need at least 3")
                && error.contains("view 00: only 0 corner candidates")
                && error.contains("view 03: only 0 corner candidates"),
            "{error}"
        );
        // A file that cannot be read stops the calibration, naming it.
        std::fs::write(dir.join("04.png"), b"\x89PNG truncated").expect("corrupt");
        let error = calibrate_data_set(&data, &CAD_CAMERA_FROM_LIDAR)
            .expect_err("corrupt png")
            .to_string();
        assert!(error.contains("04.png: not a readable PNG"), "{error}");
        std::fs::write(dir.join("05.csv"), "x_m,y_m,z_m,intensity\n").expect("empty cloud");
        std::fs::remove_file(dir.join("04.png")).expect("remove");
        std::fs::remove_file(dir.join("04.csv")).expect("remove");
        let data = DataSet::open(&dir).expect("five views");
        let error = calibrate_data_set(&data, &CAD_CAMERA_FROM_LIDAR)
            .expect_err("empty cloud")
            .to_string();
        assert!(error.contains("05.csv: empty cloud"), "{error}");
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn the_command_writes_generated_scenes_and_calibrates_from_them() {
        let dir = temp_dir("command");
        let data_dir = dir.join("scenes");
        let generated = CalibrateLidarCameraArgs {
            views: 5,
            integration_s: 2.0,
            seed: 6,
            write_generated: Some(data_dir.clone()),
            output: Some(dir.join("generated.toml")),
            ..CalibrateLidarCameraArgs::DEFAULT
        };
        let in_memory = run_calibrate_lidar_camera(&generated).expect("generated");
        let recorded = CalibrateLidarCameraArgs {
            data: Some(data_dir.clone()),
            output: Some(dir.join("recorded.toml")),
            ..CalibrateLidarCameraArgs::DEFAULT
        };
        let from_data = run_calibrate_lidar_camera(&recorded).expect("data set");
        let written = ExtrinsicFile::read(&dir.join("recorded.toml")).expect("output");
        assert_eq!(written.camera_from_lidar, from_data.camera_from_lidar);
        let (a, b) = (&from_data.camera_from_lidar, &in_memory.camera_from_lidar);
        assert!(rotation_error_rad(a, b) < 1e-6 && translation_error_m(a, b) < 1e-6);
        // Starting from the calibrated extrinsic converges to the same one.
        let restarted = CalibrateLidarCameraArgs {
            initial_extrinsic: Some(dir.join("generated.toml")),
            output: None,
            ..recorded.clone()
        };
        let again = run_calibrate_lidar_camera(&restarted).expect("from --initial-extrinsic");
        assert!(again.solution.initial_rms_px < from_data.solution.initial_rms_px);
        assert!(from_data.render().contains("px at the CAD guess ->"));
        assert!(again.render().contains("px at the initial extrinsic ->"));
        let c = &again.camera_from_lidar;
        assert!(rotation_error_rad(a, c) < 1e-6 && translation_error_m(a, c) < 1e-6);
        // An initial extrinsic that is not a rotation, or missing, is refused by name.
        let mut skewed = written;
        skewed.camera_from_lidar.rotation[0][1] += 0.2;
        std::fs::write(
            dir.join("skewed.toml"),
            toml::to_string(&skewed).expect("toml"),
        )
        .expect("write");
        for (file, expected) in [
            ("skewed.toml", "skewed.toml: camera_from_lidar.rotation"),
            ("missing.toml", "missing.toml"),
        ] {
            let args = CalibrateLidarCameraArgs {
                initial_extrinsic: Some(dir.join(file)),
                ..recorded.clone()
            };
            let error = run_calibrate_lidar_camera(&args)
                .expect_err(file)
                .to_string();
            assert!(error.contains(expected), "{error}");
        }
        let args = CalibrateLidarCameraArgs {
            data: Some(dir.join("no-such-dir")),
            ..CalibrateLidarCameraArgs::DEFAULT
        };
        let error = run_calibrate_lidar_camera(&args)
            .expect_err("missing dir")
            .to_string();
        assert!(error.contains("no-such-dir"), "{error}");
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn help_documents_the_data_set_and_data_excludes_the_scene_options() {
        use clap::{Args as _, FromArgMatches as _};
        // As the CLI's subcommand derive builds it: the variant's one-line doc comment is
        // applied after the arguments (and resets the long description).
        let command = || {
            CalibrateLidarCameraArgs::augment_args(clap::Command::new("lidar-camera"))
                .about("variant about")
                .long_about(None::<&str>)
        };
        let help = command().render_long_help().to_string();
        for needed in [
            "--data <DIR>",
            "--initial-extrinsic <FILE>",
            "--write-generated <DIR>",
            "camera.toml",
            "NN.png",
            "x_m,y_m,z_m,intensity",
            "[intrinsics]",
            "[default: 12]",
            "[default: 15]",
        ] {
            assert!(help.contains(needed), "{needed} missing from:\n{help}");
        }
        let matches = command()
            .try_get_matches_from(["lidar-camera", "--data", "captures", "--output", "x.toml"])
            .expect("data");
        let args = CalibrateLidarCameraArgs::from_arg_matches(&matches).expect("args");
        assert_eq!(args.data, Some(PathBuf::from("captures")));
        assert_eq!(args.views, CalibrateLidarCameraArgs::DEFAULT.views);
        for conflicting in ["--views", "--seed", "--write-generated"] {
            let error = command()
                .try_get_matches_from(["lidar-camera", "--data", "d", conflicting, "3"])
                .expect_err(conflicting)
                .to_string();
            assert!(error.contains("cannot be used with"), "{error}");
        }
    }
}
