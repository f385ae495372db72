//! Generator of target-based calibration scenes from a known extrinsic, for testing the
//! calibration and for `harvest calibrate lidar-camera` in simulation.
//!
//! Each view places the checkerboard ([`Checkerboard`]) at a random pose in front of the
//! sensors (inside both fields of view, lower edge roughly level as the paper asks) and produces
//! what the two sensors deliver:
//! - the camera: the view rendered as a grey image ([`crate::lidar::board_image`]: the board traced
//!   through the lens and its distortion, anti-aliased, in front of a cluttered background,
//!   blurred, with sensor noise) and the inner corners found in it by the image corner detector
//!   ([`crate::lidar::image_corners`], which is not told the pose); the true projections are kept for
//!   evaluating the detector;
//! - the LiDAR: the rosette scan of one integration window (the paper integrates 15 s per
//!   scene) intersected with the board, with the device's range and direction noise and an
//!   intensity of white or black paper plus noise. The board hangs in the air: rays that miss it
//!   return nothing.

use crate::lidar::board_image::{BoardImageConfig, GreyImage, RenderError, render_board_view};
use crate::lidar::checkerboard::Checkerboard;
use crate::lidar::image_corners::{ImageCornerConfig, ImageCornerError, detect_image_corners};
use harvest_hw::lidar::LidarSpec;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::LidarPoint;
use harvest_sim::rosette_scan::{RosetteScan, direction_from_deflection};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// How scenes are generated.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneConfig {
    /// Board placements.
    pub views: usize,
    /// LiDAR integration per view, seconds (paper: 15 s).
    pub integration_s: f64,
    /// How each view's camera image is rendered (paper grey levels, sensor noise, blur,
    /// background clutter): the `[image]` table.
    pub image: BoardImageConfig,
    /// Distance of the board centre from the camera, metres `[min, max]`.
    pub distance_m: [f64; 2],
    /// Largest tilt of the board about its horizontal and vertical axes, degrees.
    pub max_tilt_deg: f64,
    /// Largest roll of the board about its normal, degrees (lower edge roughly level).
    pub max_roll_deg: f64,
    /// Mean LiDAR intensity on white and on black paper.
    pub intensity_white: f32,
    pub intensity_black: f32,
    /// One standard deviation of the intensity noise.
    pub intensity_noise: f32,
    pub seed: u64,
}

impl Default for SceneConfig {
    fn default() -> Self {
        Self {
            views: 12,
            integration_s: 15.0,
            image: BoardImageConfig::default(),
            distance_m: [1.5, 3.0],
            max_tilt_deg: 30.0,
            max_roll_deg: 8.0,
            intensity_white: 110.0,
            intensity_black: 12.0,
            intensity_noise: 6.0,
            seed: 1,
        }
    }
}

/// One board placement as both sensors see it.
#[derive(Debug, Clone)]
pub struct CalibrationView {
    /// True board pose (evaluation only).
    pub camera_from_board: RigidTransform,
    /// Inner corners found in the rendered image, row by row like [`Checkerboard::corners_m`],
    /// pixels; or why the board was not found there.
    pub image_corners_px: Result<Vec<[f64; 2]>, ImageCornerError>,
    /// True projections of the inner corners, same order (evaluation of the detector only).
    pub true_image_corners_px: Vec<[f64; 2]>,
    /// The rendered camera image the corners were found in (kept for writing the scenes as a
    /// data set, [`crate::lidar::calibration_data`]).
    pub image: GreyImage,
    /// The LiDAR returns of the integration window, LiDAR frame.
    pub cloud: Vec<LidarPoint>,
}

/// A calibration data set.
#[derive(Debug, Clone)]
pub struct CalibrationScenes {
    pub intrinsics: CameraIntrinsics,
    pub board: Checkerboard,
    /// The extrinsic the scenes were generated with (what calibration should recover).
    pub true_camera_from_lidar: RigidTransform,
    pub views: Vec<CalibrationView>,
}

/// Why scenes could not be generated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SceneError {
    /// A configuration value is unusable.
    #[error("calibration scenes: {0}")]
    Config(String),
    /// A view's image could not be rendered.
    #[error("view {view}: {source}")]
    Render { view: usize, source: RenderError },
    /// No pose put the whole board inside both fields of view.
    #[error(
        "no board pose at {distance_m:?} m puts all corners in the image and the board in the \
         LiDAR's field of view after {attempts} attempts"
    )]
    NoValidPose {
        distance_m: [f64; 2],
        attempts: usize,
    },
}

/// Generates `config.views` views of `board` seen by a camera with `intrinsics` and a LiDAR
/// (`spec`) mounted at `true_camera_from_lidar`.
pub fn generate_scenes(
    config: &SceneConfig,
    intrinsics: CameraIntrinsics,
    spec: &LidarSpec,
    board: Checkerboard,
    true_camera_from_lidar: RigidTransform,
) -> Result<CalibrationScenes, SceneError> {
    board.validate().map_err(SceneError::Config)?;
    spec.validate().map_err(SceneError::Config)?;
    let [near, far] = config.distance_m;
    if !(near.is_finite() && far.is_finite() && near > 0.3 && far >= near) {
        return Err(SceneError::Config(format!(
            "distance_m = {:?} must be increasing and beyond 0.3 m",
            config.distance_m
        )));
    }
    if !(config.integration_s.is_finite() && config.integration_s > 0.0) {
        return Err(SceneError::Config(format!(
            "integration_s = {} is not positive",
            config.integration_s
        )));
    }
    for (key, value) in [
        ("max_tilt_deg", config.max_tilt_deg),
        ("max_roll_deg", config.max_roll_deg),
    ] {
        if !(value.is_finite() && (0.0..=80.0).contains(&value)) {
            return Err(SceneError::Config(format!(
                "{key} = {value} outside 0..=80 deg"
            )));
        }
    }
    config
        .image
        .validate()
        .map_err(|reason| SceneError::Config(format!("image.{reason}")))?;
    let detector = ImageCornerConfig::default();
    let mut rng = SmallRng::seed_from_u64(config.seed);
    let lidar_from_camera = true_camera_from_lidar.inverse();
    let mut views = Vec::with_capacity(config.views);
    for view in 0..config.views {
        let camera_from_board = sample_board_pose(
            config,
            &intrinsics,
            spec,
            &board,
            &lidar_from_camera,
            &mut rng,
        )?;
        let true_image_corners_px = board
            .corners_m()
            .into_iter()
            .filter_map(|[x, y]| intrinsics.project(camera_from_board.apply([x, y, 0.0])))
            .map(|(u, v)| [u, v])
            .collect();
        let mut image_rng = SmallRng::seed_from_u64(rng.random());
        let image = render_board_view(
            &intrinsics,
            &board,
            &camera_from_board,
            &config.image,
            &mut image_rng,
        )
        .map_err(|source| SceneError::Render { view, source })?;
        let image_corners_px =
            detect_image_corners(&image, &board, &detector).map(|found| found.corners_px);
        if let Err(error) = &image_corners_px {
            tracing::debug!(view, %error, "board not found in the rendered image");
        }
        let lidar_from_board = lidar_from_camera.compose(&camera_from_board);
        let cloud = scan_board(config, spec, &board, &lidar_from_board, &mut rng)?;
        tracing::debug!(view, points = cloud.len(), "calibration view generated");
        views.push(CalibrationView {
            camera_from_board,
            image_corners_px,
            true_image_corners_px,
            image,
            cloud,
        });
    }
    Ok(CalibrationScenes {
        intrinsics,
        board,
        true_camera_from_lidar,
        views,
    })
}

fn sample_board_pose(
    config: &SceneConfig,
    intrinsics: &CameraIntrinsics,
    spec: &LidarSpec,
    board: &Checkerboard,
    lidar_from_camera: &RigidTransform,
    rng: &mut SmallRng,
) -> Result<RigidTransform, SceneError> {
    const ATTEMPTS: usize = 10_000;
    const MARGIN_PX: f64 = 15.0;
    let [near, far] = config.distance_m;
    let half_w = board.width_m() / 2.0;
    let half_h = board.height_m() / 2.0;
    let outline = [
        [-half_w, -half_h],
        [half_w, -half_h],
        [half_w, half_h],
        [-half_w, half_h],
    ];
    let lidar_limit = spec.half_fov_rad() * 0.95;
    for _ in 0..ATTEMPTS {
        let distance = rng.random_range(near..=far);
        let x = rng.random_range(-0.35..=0.35) * distance;
        let y = rng.random_range(-0.15..=0.15) * distance;
        let tilt = config.max_tilt_deg.to_radians();
        let roll = config.max_roll_deg.to_radians();
        // Board frame x right, y down, z away: identity faces the camera squarely.
        let pose = RigidTransform::from_rpy_translation(
            rng.random_range(-tilt..=tilt),
            rng.random_range(-tilt..=tilt),
            rng.random_range(-roll..=roll),
            [x, y, distance],
        );
        let in_image = board.corners_m().iter().chain(&outline).all(|[bx, by]| {
            intrinsics
                .project(pose.apply([*bx, *by, 0.0]))
                .is_some_and(|(u, v)| {
                    u > MARGIN_PX
                        && v > MARGIN_PX
                        && u < intrinsics.width_px as f64 - MARGIN_PX
                        && v < intrinsics.height_px as f64 - MARGIN_PX
                })
        });
        let in_lidar = outline.iter().all(|[bx, by]| {
            let p = lidar_from_camera.apply(pose.apply([*bx, *by, 0.0]));
            let norm = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            norm > 0.0 && (p[0] / norm).clamp(-1.0, 1.0).acos() < lidar_limit
        });
        if in_image && in_lidar {
            return Ok(pose);
        }
    }
    Err(SceneError::NoValidPose {
        distance_m: config.distance_m,
        attempts: ATTEMPTS,
    })
}

/// The LiDAR returns of one integration window on a board hanging in the air.
fn scan_board(
    config: &SceneConfig,
    spec: &LidarSpec,
    board: &Checkerboard,
    lidar_from_board: &RigidTransform,
    rng: &mut SmallRng,
) -> Result<Vec<LidarPoint>, SceneError> {
    let to_config = |error: rand_distr::NormalError| SceneError::Config(error.to_string());
    let range_noise = Normal::new(0.0, spec.range_sigma_m.max(1e-12)).map_err(to_config)?;
    let angle_noise =
        Normal::new(0.0, spec.angular_sigma_deg.to_radians().max(1e-12)).map_err(to_config)?;
    let intensity_noise =
        Normal::new(0.0, f64::from(config.intensity_noise).max(1e-12)).map_err(to_config)?;
    let board_from_lidar = lidar_from_board.inverse();
    let normal = lidar_from_board.rotate([0.0, 0.0, 1.0]);
    let centre = lidar_from_board.translation_m;
    let n_dot_c = normal[0] * centre[0] + normal[1] * centre[1] + normal[2] * centre[2];
    let scan = RosetteScan::new(spec);
    let start = rng.random_range(0..1_000_000_000u64);
    let count = (config.integration_s * spec.point_rate_hz) as u64;
    let period_s = 1.0 / spec.point_rate_hz;
    let mut cloud = Vec::new();
    for index in start..start + count {
        let [dy, dz] = scan.deflection_rad(index as f64 * period_s);
        let direction =
            direction_from_deflection([dy + angle_noise.sample(rng), dz + angle_noise.sample(rng)]);
        let facing = normal[0] * direction[0] + normal[1] * direction[1] + normal[2] * direction[2];
        if facing.abs() < 1e-9 {
            continue;
        }
        let t = n_dot_c / facing;
        if !(t > spec.range_m[0] && t < spec.range_m[1]) {
            continue;
        }
        let hit = direction.map(|d| d * t);
        let [bx, by, _] = board_from_lidar.apply(hit);
        let Some(white) = board.is_white(bx, by) else {
            continue;
        };
        let mean = if white {
            config.intensity_white
        } else {
            config.intensity_black
        };
        let intensity = (f64::from(mean) + intensity_noise.sample(rng)).clamp(0.0, 255.0) as f32;
        let range = t + range_noise.sample(rng);
        cloud.push(LidarPoint {
            x_m: (direction[0] * range) as f32,
            y_m: (direction[1] * range) as f32,
            z_m: (direction[2] * range) as f32,
            intensity,
        });
    }
    Ok(cloud)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_keys_take_an_image_table_and_refuse_the_old_pixel_noise() {
        let config: SceneConfig =
            toml::from_str("views = 4\n[image]\nnoise_grey = 5.0\nblur_px = 1.0\n")
                .expect("image table");
        assert_eq!(config.views, 4);
        assert_eq!(config.image.noise_grey, 5.0);
        assert_eq!(
            config.image.white_grey,
            BoardImageConfig::default().white_grey
        );
        let error = toml::from_str::<SceneConfig>("pixel_noise_px = 0.3\n").expect_err("old key");
        assert!(error.to_string().contains("pixel_noise_px"), "{error}");
        let error = toml::from_str::<SceneConfig>("[image]\nnoise_px = 1.0\n").expect_err("typo");
        assert!(error.to_string().contains("noise_px"), "{error}");
        let bad = SceneConfig {
            image: BoardImageConfig {
                noise_grey: -1.0,
                ..BoardImageConfig::default()
            },
            ..SceneConfig::default()
        };
        let error = generate_scenes(
            &bad,
            CameraIntrinsics::tl460_rgb(),
            &LidarSpec::mid70(),
            Checkerboard::paper(),
            RigidTransform::IDENTITY,
        )
        .expect_err("negative noise");
        assert!(
            error.to_string().contains("image.noise_grey = -1"),
            "{error}"
        );
    }
}
