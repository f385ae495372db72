//! `harvest eval lidar`: the Table-III-style comparison of fused LiDAR-camera localization with
//! the ToF camera path, in the simulated orchard, and the fusion time.
//!
//! Set-up per distance (the paper's 0.5, 1.2 and 1.8 m): the `ideal` orchard (apples on a grid,
//! nothing occluding), the camera moved to look straight at the apple nearest the grid centre
//! from that distance. The apple's instance mask is the simulator's true label image of the
//! colour camera (a perfect segmentation, so only the depth source differs). Repeated
//! localizations of that apple, each from fresh sensor data:
//! - **LiDAR-camera**: one integration window of the simulated Mid-70 (the scan continues, so
//!   every window samples new directions; fresh range noise), fused into the colour image
//!   ([`Fusion`]) with the LiDAR's true extrinsic, mask points, Z-score centroid, eq. 20;
//! - **ToF**: one rendered depth frame of the simulated TL460 (fresh per-pixel noise), every
//!   depth pixel registered into the colour image through the frame's `color_from_depth`, mask
//!   points, the same Z-score centroid, eq. 20.
//!
//! Reported per distance and path: the standard deviation of the repeated positions (robot
//! frame; `sqrt` of the summed per-axis variances, and per axis), the mean number of mask points,
//! and the distance of the mean position from the true apple centre (the visible-surface bias of
//! a centroid). The paper's Table III values are printed alongside.
//!
//! Caveat: the simulated ToF noise is independent per pixel and per frame, so averaging hundreds
//! of mask pixels shrinks it; a real ToF/stereo camera's error is spatially correlated (the paper's
//! D455 spread grows with distance), which this simulation does not model.

use harvest_hw::lidar::LidarSpec;
use harvest_ipc::payloads::{LidarPoint, PointCloud};
use harvest_lidar::fusion::{Fusion, FusionConfig, FusionError, FusionTiming, measure_fusion_time};
use harvest_lidar::integration_window::{max_window_s, window_returns};
use harvest_lidar::localization::{ZScoreConfig, localize_fruit};
use harvest_sim::lidar_device::{LidarDeviceConfig, LidarDeviceError, LidarDeviceServer};
use harvest_sim::render_rgbd::label;
use harvest_sim::rosette_scan::RosetteScan;
use harvest_sim::rosette_scan::coverage_fraction;
use harvest_sim::{RgbdRenderer, Scenario, World};
use std::fmt::Write as _;

/// `harvest eval lidar`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalLidarArgs {
    /// Repeated localizations per distance and depth source.
    #[arg(long, default_value_t = 20)]
    pub trials: usize,
    /// LiDAR integration per localization, seconds (at most 1 s: the cloud's capacity).
    #[arg(long, default_value_t = 1.0)]
    pub integration_s: f64,
    /// Distances of the camera from the apple, metres.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1.2,1.8")]
    pub distances_m: Vec<f64>,
    /// World and noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Runs of the fusion-time measurement.
    #[arg(long, default_value_t = 30)]
    pub fusion_runs: usize,
}

/// Why the evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum EvalLidarError {
    #[error("eval lidar: {0}")]
    Config(String),
    #[error(transparent)]
    Scenario(#[from] harvest_sim::ScenarioError),
    #[error(transparent)]
    Orchard(#[from] harvest_sim::OrchardError),
    #[error(transparent)]
    Render(#[from] harvest_sim::RenderError),
    #[error(transparent)]
    Device(#[from] LidarDeviceError),
    #[error(transparent)]
    Fusion(#[from] FusionError),
}

/// Repeatability of one depth source at one distance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Repeatability {
    pub trials: usize,
    /// Trials that gave a position.
    pub localized: usize,
    /// `sqrt(var_x + var_y + var_z)` of the positions, centimetres.
    pub std_cm: f64,
    /// Per robot axis, centimetres.
    pub std_axes_cm: [f64; 3],
    /// Mean mask points per localization.
    pub mean_points: f64,
    /// Distance of the mean position from the true apple centre, centimetres.
    pub bias_cm: f64,
}

/// One row of the Table-III-style report.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DistanceRow {
    pub distance_m: f64,
    pub lidar: Repeatability,
    pub tof: Repeatability,
}

/// The report.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EvalLidarReport {
    pub rows: Vec<DistanceRow>,
    pub integration_s: f64,
    pub fusion: FusionTiming,
    /// Share of the field of view (0.25 deg cells) the rosette covers after each integration
    /// time: `(seconds, share)`.
    pub coverage: Vec<(f64, f64)>,
}

/// Integration times at which the scan coverage is reported, seconds.
pub const COVERAGE_TIMES_S: [f64; 5] = [0.1, 0.2, 0.5, 1.0, 2.0];

/// The paper's Table III (LiDAR-RGB, RS-D455) at 0.5, 1.2 and 1.8 m, centimetres.
pub const PAPER_TABLE_III_CM: [(f64, f64, f64); 3] = [
    (0.5, 0.245, 1.006),
    (1.2, 0.227, 1.175),
    (1.8, 0.275, 1.360),
];

fn repeatability(
    positions: &[[f64; 3]],
    trials: usize,
    points: usize,
    truth: [f64; 3],
) -> Repeatability {
    let n = positions.len();
    let mut mean = [0.0; 3];
    for p in positions {
        for k in 0..3 {
            mean[k] += p[k] / n.max(1) as f64;
        }
    }
    let mut variance = [0.0; 3];
    for p in positions {
        for k in 0..3 {
            variance[k] += (p[k] - mean[k]).powi(2) / (n.max(2) - 1) as f64;
        }
    }
    let bias = (0..3)
        .map(|k| (mean[k] - truth[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    Repeatability {
        trials,
        localized: n,
        std_cm: 100.0 * variance.iter().sum::<f64>().sqrt(),
        std_axes_cm: variance.map(|v| 100.0 * v.sqrt()),
        mean_points: points as f64 / n.max(1) as f64,
        bias_cm: 100.0 * bias,
    }
}

/// The target apple and its world with the camera `distance_m` in front of it.
fn world_at_distance(
    seed: u64,
    distance_m: f64,
) -> Result<(World, u32, [f64; 3], f64), EvalLidarError> {
    let mut scenario = Scenario::preset("ideal")?;
    let reference = World::generate(&scenario, seed)?;
    let (mid_y, mid_z) = {
        let apples = reference.apples();
        let n = apples.len().max(1) as f64;
        (
            apples.iter().map(|a| a.center_in_robot_m[1]).sum::<f64>() / n,
            apples.iter().map(|a| a.center_in_robot_m[2]).sum::<f64>() / n,
        )
    };
    let target = reference
        .apples()
        .iter()
        .min_by(|a, b| {
            let d = |c: [f64; 3]| (c[1] - mid_y).hypot(c[2] - mid_z);
            d(a.center_in_robot_m).total_cmp(&d(b.center_in_robot_m))
        })
        .ok_or_else(|| EvalLidarError::Config("the ideal scenario has no apple".into()))?;
    let (id, centre, radius) = (target.id.0, target.center_in_robot_m, target.radius_m);
    scenario.camera.position_in_robot_m = [centre[0] - distance_m, centre[1], centre[2]];
    scenario.camera.look_at_in_robot_m = centre;
    let world = World::generate(&scenario, seed)?;
    let moved = world
        .apples()
        .iter()
        .find(|a| a.id.0 == id)
        .map(|a| a.center_in_robot_m);
    if moved != Some(centre) {
        return Err(EvalLidarError::Config(format!(
            "apple {id} moved when the camera moved ({centre:?} -> {moved:?})"
        )));
    }
    Ok((world, id, centre, radius))
}

/// Runs the comparison and the fusion-time measurement.
pub fn evaluate(args: &EvalLidarArgs) -> Result<EvalLidarReport, EvalLidarError> {
    let device_config = LidarDeviceConfig {
        noise_seed: args.seed,
        ..LidarDeviceConfig::default()
    };
    let Some(per_window) = window_returns(&device_config.spec, args.integration_s) else {
        return Err(EvalLidarError::Config(format!(
            "integration_s = {} outside (0, {}] (one cloud holds {} points)",
            args.integration_s,
            max_window_s(&device_config.spec),
            harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY
        )));
    };
    if args.trials < 2 {
        return Err(EvalLidarError::Config(format!(
            "trials = {} (a standard deviation needs at least 2)",
            args.trials
        )));
    }
    let zscore = ZScoreConfig::default();
    let mut cloud: Box<PointCloud> = harvest_ipc::payload::boxed_zeroed();
    let mut rows = Vec::new();
    let mut timing_points = None;
    for &distance_m in &args.distances_m {
        if !(distance_m.is_finite() && (0.3..=5.0).contains(&distance_m)) {
            return Err(EvalLidarError::Config(format!(
                "distance {distance_m} m outside 0.3-5 m"
            )));
        }
        let (world, apple_id, centre, _radius) = world_at_distance(args.seed, distance_m)?;
        let mut renderer = RgbdRenderer::new(&world.scenario().camera)?;
        let color = *renderer.color_intrinsics();
        let depth = *renderer.depth_intrinsics();
        let mut labels = vec![0u32; (color.width_px * color.height_px) as usize];
        renderer.render_labels(&world, &mut labels)?;
        let apple_label = label::APPLE_BASE + apple_id;
        let mask: Vec<bool> = labels.iter().map(|&l| l == apple_label).collect();
        let robot_from_color = renderer.robot_from_color();
        let color_from_depth = robot_from_color
            .inverse()
            .compose(&renderer.robot_from_depth());
        // ToF path: the depth pixels registered into the colour image by the same projection
        // and occlusion handling as the LiDAR points.
        let mut depth_mm = vec![0u16; (depth.width_px * depth.height_px) as usize];
        let depth_rays = depth.pixel_ray_table();
        let mut tof_cloud = Vec::with_capacity(depth_mm.len());
        let mut tof_fusion = Fusion::new(FusionConfig::new(color, color_from_depth))?;
        let mut points = Vec::new();
        let (mut tof_positions, mut tof_points) = (Vec::new(), 0usize);
        for trial in 0..args.trials {
            renderer.render_depth(&world, trial as u64 + 1, &mut depth_mm)?;
            depth_points(&depth_mm, &depth_rays, &mut tof_cloud);
            tof_fusion.fuse(&tof_cloud)?;
            tof_fusion.points_in_mask(|pixel| mask[pixel], &mut points);
            if let Ok(fruit) = localize_fruit(&points, &robot_from_color, &zscore) {
                tof_positions.push(fruit.position_in_robot_m);
                tof_points += fruit.points_in_mask;
            }
        }
        // LiDAR path.
        let mut device = LidarDeviceServer::new(device_config)?;
        let mut fusion = Fusion::new(
            FusionConfig::new(color, device_config.camera_from_lidar)
                .with_range_noise(device_config.spec.range_sigma_m),
        )?;
        let (mut lidar_positions, mut lidar_points) = (Vec::new(), 0usize);
        for _ in 0..args.trials {
            cloud.clear();
            device.scan_into(&world, per_window, &mut cloud);
            fusion.fuse(cloud.valid_points())?;
            fusion.points_in_mask(|pixel| mask[pixel], &mut points);
            if let Ok(fruit) = localize_fruit(&points, &robot_from_color, &zscore) {
                lidar_positions.push(fruit.position_in_robot_m);
                lidar_points += fruit.points_in_mask;
            }
        }
        if timing_points.is_none() {
            // A full cloud for the timing: the whole capacity, whatever the window asked.
            cloud.clear();
            device.scan_into(
                &world,
                2 * harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY,
                &mut cloud,
            );
            timing_points = Some((*fusion.config(), cloud.valid_points().to_vec()));
        }
        let row = DistanceRow {
            distance_m,
            lidar: repeatability(&lidar_positions, args.trials, lidar_points, centre),
            tof: repeatability(&tof_positions, args.trials, tof_points, centre),
        };
        tracing::info!(?row, "distance evaluated");
        rows.push(row);
    }
    let (config, points) =
        timing_points.ok_or_else(|| EvalLidarError::Config("no distance given".into()))?;
    let fusion = measure_fusion_time(config, &points, args.fusion_runs)?;
    Ok(EvalLidarReport {
        rows,
        integration_s: args.integration_s,
        fusion,
        coverage: scan_coverage(&device_config.spec),
    })
}

/// Coverage of the field of view by the rosette after each of [`COVERAGE_TIMES_S`].
pub fn scan_coverage(spec: &LidarSpec) -> Vec<(f64, f64)> {
    let longest = COVERAGE_TIMES_S.iter().copied().fold(0.0, f64::max);
    let mut scan = RosetteScan::new(spec);
    let mut directions = Vec::new();
    scan.next_directions((longest * spec.point_rate_hz) as usize, &mut directions);
    COVERAGE_TIMES_S
        .iter()
        .map(|&seconds| {
            let count = ((seconds * spec.point_rate_hz) as usize).min(directions.len());
            let share = coverage_fraction(&directions[..count], spec.half_fov_rad(), 0.25);
            (seconds, share)
        })
        .collect()
}

/// The valid pixels of a depth image (millimetres, 0 = no return) as points in the depth
/// camera frame, replacing `out`; `rays` is the camera's pixel ray table.
fn depth_points(depth_mm: &[u16], rays: &[[f32; 2]], out: &mut Vec<LidarPoint>) {
    out.clear();
    for (&d, &[x, y]) in depth_mm.iter().zip(rays) {
        if d == 0 {
            continue;
        }
        let z = f32::from(d) / 1000.0;
        out.push(LidarPoint {
            x_m: x * z,
            y_m: y * z,
            z_m: z,
            intensity: 0.0,
        });
    }
}

impl EvalLidarReport {
    /// The Table-III-style text.
    pub fn render(&self) -> String {
        let mut text = String::new();
        let _ = writeln!(
            text,
            "Fruit localization repeatability (Table III style): std of repeated positions, cm \
             (LiDAR window {:.2} s; both paths: true mask, Z-score centroid, eq. 20)",
            self.integration_s
        );
        let _ = writeln!(
            text,
            "\ndistance  LiDAR-cam std  ToF std   | paper LiDAR-RGB  paper RS-D455 | LiDAR pts  ToF pts  | LiDAR bias  ToF bias"
        );
        for row in &self.rows {
            let paper = PAPER_TABLE_III_CM
                .iter()
                .find(|(d, _, _)| (d - row.distance_m).abs() < 1e-6);
            let (paper_lidar, paper_d455) = paper.map_or(("-".to_owned(), "-".to_owned()), |p| {
                (format!("{:.3}", p.1), format!("{:.3}", p.2))
            });
            let _ = writeln!(
                text,
                "{:>6.2} m  {:>13.3}  {:>7.3}   | {:>15}  {:>13} | {:>9.0}  {:>7.0}  | {:>7.2} cm  {:>5.2} cm",
                row.distance_m,
                row.lidar.std_cm,
                row.tof.std_cm,
                paper_lidar,
                paper_d455,
                row.lidar.mean_points,
                row.tof.mean_points,
                row.lidar.bias_cm,
                row.tof.bias_cm,
            );
        }
        let _ = writeln!(
            text,
            "\nper-axis std (robot x, y, z), cm; localized / trials"
        );
        for row in &self.rows {
            let axes = |r: &Repeatability| {
                format!(
                    "{:.3} {:.3} {:.3} ({}/{})",
                    r.std_axes_cm[0], r.std_axes_cm[1], r.std_axes_cm[2], r.localized, r.trials
                )
            };
            let _ = writeln!(
                text,
                "{:>6.2} m  LiDAR-cam {}   ToF {}",
                row.distance_m,
                axes(&row.lidar),
                axes(&row.tof)
            );
        }
        let coverage: Vec<String> = self
            .coverage
            .iter()
            .map(|(seconds, share)| format!("{seconds:.1} s {:.0} %", 100.0 * share))
            .collect();
        let _ = writeln!(
            text,
            "\nrosette coverage of the 70.4 deg field of view (0.25 deg cells): {}",
            coverage.join(", ")
        );
        let f = &self.fusion;
        let _ = writeln!(
            text,
            "\nfusion of one cloud ({} points) into {}x{}: median {:.2} ms, max {:.2} ms over {} \
             runs (one thread)",
            f.points, f.width_px, f.height_px, f.median_ms, f.max_ms, f.runs
        );
        text
    }
}

/// Runs `harvest eval lidar` and prints the report.
pub fn run_eval_lidar(args: &EvalLidarArgs) -> Result<EvalLidarReport, EvalLidarError> {
    let report = evaluate(args)?;
    print!("{}", report.render());
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fused_and_tof_localization_are_repeatable_and_near_the_apple() {
        let args = EvalLidarArgs {
            trials: 4,
            integration_s: 0.5,
            distances_m: vec![1.2],
            seed: 1,
            fusion_runs: 1,
        };
        let report = evaluate(&args).expect("evaluate");
        let row = report.rows[0];
        for path in [row.lidar, row.tof] {
            assert_eq!(path.localized, 4, "{}", report.render());
            assert!(path.mean_points > 20.0, "{}", report.render());
            // The centroid of the visible surface lies about half a radius (~2 cm) in front.
            assert!(path.bias_cm < 4.0, "{}", report.render());
            assert!(path.std_cm < 1.0, "{}", report.render());
        }
        assert_eq!(report.fusion.points, 100_000);
        assert!(report.render().contains("LiDAR-cam std"));
    }

    #[test]
    fn bad_arguments_are_refused() {
        let mut args = EvalLidarArgs {
            trials: 4,
            integration_s: 1.5,
            distances_m: vec![1.2],
            seed: 1,
            fusion_runs: 1,
        };
        assert!(matches!(evaluate(&args), Err(EvalLidarError::Config(_))));
        args.integration_s = 0.5;
        args.trials = 1;
        assert!(matches!(evaluate(&args), Err(EvalLidarError::Config(_))));
    }
}
