//! `harvest eval laser`: what the ALACS scan adds to the ToF camera's apple localisation, on
//! simulated orchards ([alacs sec. 3]: the RGB-D camera gives a rough location, the laser
//! scan refines it).
//!
//! Per seeded world of the scenario:
//! 1. **ToF path.** The simulator renders the ToF camera's colour and depth frames and the
//!    perception pipeline ([`Perception`], the code the perception process runs) localises the
//!    apples in the colour-camera frame. Its extrinsic calibration is the simulator's true
//!    colour-sensor pose, so the ToF error is perception's own. Each estimate is paired with the
//!    true apple whose centre is nearest, within 2 true radii, one to one, nearest pairs first.
//! 2. **Laser path.** Each paired estimate becomes a scan request (rough centre and radius in
//!    the ToF colour-camera frame) answered by [`ScanService`], the code the laser process runs,
//!    on the simulator's ALACS device ([`AlacsDeviceServer`]) driven in-process through the same
//!    command/answer path the `hw/alacs/*` channels carry. Apples are scanned one after another,
//!    so the slide starts each scan where the previous one left it.
//! 3. **Errors.** Euclidean distance between estimate and true centre, before (ToF) and after
//!    (laser), on the apples the scan refined; per-axis absolute errors in the ALACS camera frame
//!    (x horizontal, y vertical, z depth) against the paper's bounds (0.6, 1.2, 4 mm, section 5.2).
//! 4. **Time.** A scan's cost on the robot: slide travel / speed + a settling time per move + an
//!    exposure-and-transfer time per image (a model with stated parameters: the simulator does
//!    not move a slide) + the measured processing (planning, extraction, triangulation, fitting,
//!    selection: the scan's wall time minus the time spent inside the device calls). Run it with
//!    `--release` for representative processing times. The simulator's render time is reported
//!    separately; it is not robot time.

use std::fmt::Write as _;
use std::path::PathBuf;

use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsError, alacs_camera_intrinsics};
use harvest_ipc::WireCode;
use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::payloads::rgbd_frame::{DEPTH_PIXELS, RGB_BYTES};
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, LaserScanStatus};
use harvest_perception::camera_setup::CameraSetup;
use harvest_perception::estimator::EstimatorKind;
use harvest_perception::pipeline::PerceptionSetupError;
use harvest_perception::{AppleEstimate, DepthView, Perception, PerceptionConfig, RgbView};
use harvest_sim::alacs_device::{AlacsDeviceConfig, AlacsDeviceServer, LocalAlacsUnit};
use harvest_sim::process::load_scenario;
use harvest_sim::{AppleState, RenderError, RgbdRenderer, Scenario, ScenarioError, World};
use serde::Serialize;

use crate::laser::report_table::write_summary_table;

use crate::laser::accuracy::PAPER_MAX_ERROR_MM;
use harvest_laser::extraction::ExtractionError;
use harvest_laser::service::ScanService;

/// A ToF estimate pairs with a true apple within this many true radii.
pub const MATCH_RADII: f64 = 2.0;

/// Arguments of `harvest eval laser`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct EvalLaserArgs {
    /// Scenario preset name or path to a scenario TOML file.
    #[arg(long, default_value = "default")]
    pub scenario: String,
    /// Seed of the first world; the others use the following seeds.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Number of seeded worlds.
    #[arg(long, default_value_t = 10)]
    pub worlds: u32,
    /// Perception estimator giving the ToF (rough) positions.
    #[arg(long, default_value = "sphere-fit")]
    pub estimator: EstimatorKind,
    /// Slide speed of the time model, m/s.
    #[arg(long, default_value_t = 0.1)]
    pub slide_speed_m_s: f64,
    /// Settling time after each slide move, ms.
    #[arg(long, default_value_t = 50.0)]
    pub settle_ms: f64,
    /// Exposure, readout and transfer of one image, ms.
    #[arg(long, default_value_t = 40.0)]
    pub capture_ms: f64,
    /// Also write the report (with every apple) as JSON to this file.
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Scan only the apples perception's scan policy asks for, as the running stack does
    /// (tracks over frames, scans answered after their modelled duration, refined positions
    /// applied to later detections), and report the published positions with and without the
    /// scans. Without it every paired apple is scanned.
    #[arg(long)]
    pub policy: bool,
    /// Perception configuration (TOML) whose `[laser]` policy is used with --policy; default:
    /// perception's built-in values.
    #[arg(long, value_name = "PATH")]
    pub perception_config: Option<PathBuf>,
    /// With --policy: simulated time per world, s.
    #[arg(long, default_value_t = 12.0)]
    pub duration_s: f64,
    /// With --policy: time between the camera frames perception processes, ms.
    #[arg(long, default_value_t = 200.0)]
    pub frame_interval_ms: f64,
}

/// Why the evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum EvalLaserError {
    #[error("--{name} {value} is invalid: {reason}")]
    InvalidArgument {
        name: &'static str,
        value: String,
        reason: &'static str,
    },
    #[error("scenario {scenario:?}: {source}")]
    Scenario {
        scenario: String,
        #[source]
        source: Box<ScenarioError>,
    },
    #[error("world of seed {seed}: {source}")]
    World {
        seed: u64,
        #[source]
        source: harvest_sim::OrchardError,
    },
    #[error("ToF render: {0}")]
    Render(#[from] RenderError),
    #[error("perception setup: {0}")]
    Perception(#[from] PerceptionSetupError),
    #[error("simulated ALACS: {0}")]
    Alacs(#[from] AlacsError),
    #[error("scan pipeline: {0}")]
    Scan(#[from] ExtractionError),
    #[error("cannot write {path}: {source}")]
    WriteJson {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot encode the JSON report: {0}")]
    Json(#[from] serde_json::Error),
    #[error("cannot print the report: {0}")]
    Output(#[source] std::io::Error),
}

/// Parameters of the scan-time model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimingModel {
    pub slide_speed_m_s: f64,
    pub settle_ms: f64,
    pub capture_ms: f64,
}

/// One paired apple.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AppleRecord {
    pub world_seed: u64,
    pub apple_index: u32,
    /// `LaserScanResult::status` of its scan.
    pub status: WireCode<LaserScanStatus>,
    pub distance_m: f64,
    /// ToF radius minus true radius, mm (the scan takes the apple's size from the request).
    pub radius_error_mm: f64,
    pub error_before_mm: f64,
    /// Error of the scan's answer (fused sphere, else selected candidate); `None` unless the
    /// scan refined the position.
    pub error_after_mm: Option<f64>,
    /// Error of the selected single-image candidate (the paper's strategy), mm.
    pub selected_error_mm: Option<f64>,
    /// Fused sphere's radius minus the true radius, mm; `None` when the circles did not fuse.
    pub fused_radius_error_mm: Option<f64>,
    /// ALACS-frame (x, y, z) errors before and after, mm (after: zero unless refined).
    pub axis_error_before_mm: [f64; 3],
    pub axis_error_after_mm: [f64; 3],
    pub candidates: u8,
    pub slide_travel_mm: f64,
    pub moves: usize,
    pub captures: usize,
    pub processing_ms: f64,
    pub modelled_scan_ms: f64,
    pub simulator_ms: f64,
}

/// Distribution of a positive quantity.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Summary {
    pub count: usize,
    pub mean: f64,
    pub median: f64,
    pub p95: f64,
    pub max: f64,
}

impl Summary {
    pub fn of(values: impl IntoIterator<Item = f64>) -> Self {
        let mut values: Vec<f64> = values.into_iter().filter(|v| v.is_finite()).collect();
        if values.is_empty() {
            return Self::default();
        }
        values.sort_by(f64::total_cmp);
        let quantile = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
        Self {
            count: values.len(),
            mean: values.iter().sum::<f64>() / values.len() as f64,
            median: quantile(0.5),
            p95: quantile(0.95),
            max: values[values.len() - 1],
        }
    }

    /// The five columns of a report table row (`n mean median p95 max`, see
    /// [`crate::laser::report_table`]).
    pub fn columns(&self) -> String {
        format!(
            "{:>4} {:>8.2} {:>8.2} {:>8.2} {:>8.2}",
            self.count, self.mean, self.median, self.p95, self.max
        )
    }
}

/// The evaluation's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefinementReport {
    pub scenario: String,
    pub first_seed: u64,
    pub worlds: u32,
    pub estimator: String,
    pub timing: TimingModel,
    pub apples_generated: usize,
    /// ToF estimates paired with a true apple.
    pub apples_paired: usize,
    pub refined: usize,
    pub no_laser_line: usize,
    pub out_of_reach: usize,
    pub device_errors: usize,
    /// ToF error over every paired apple, mm.
    pub tof_error_all_mm: Summary,
    /// ToF and laser errors over the refined apples, mm.
    pub tof_error_mm: Summary,
    pub laser_error_mm: Summary,
    /// The selected single-image candidates' errors over the refined apples, mm.
    pub selected_candidate_error_mm: Summary,
    /// Refined apples whose answer is the fused sphere.
    pub fused: usize,
    /// The answer's error split by how it was found, mm.
    pub laser_error_fused_mm: Summary,
    pub laser_error_unfused_mm: Summary,
    /// |ToF radius - true| and |fused radius - true| over the fused apples, mm.
    pub tof_radius_error_mm: Summary,
    pub fused_radius_error_mm: Summary,
    /// Mean absolute ALACS-frame (x, y, z) errors over the refined apples, mm.
    pub tof_mean_axis_error_mm: [f64; 3],
    pub laser_mean_axis_error_mm: [f64; 3],
    pub laser_max_axis_error_mm: [f64; 3],
    /// Refined apples whose laser error is below their ToF error.
    pub improved: usize,
    /// Refined apples within the paper's per-axis bounds.
    pub within_paper_bounds: usize,
    /// Over the scans that ran the slide (refined or no line).
    pub modelled_scan_ms: Summary,
    pub processing_ms: Summary,
    pub slide_travel_mm: Summary,
    pub simulator_ms: Summary,
    pub apples: Vec<AppleRecord>,
}

/// Runs the evaluation (every paired apple scanned, or with `--policy` perception's scan
/// policy), prints the summary to stdout and writes the JSON report if asked.
pub fn run_eval_laser(args: &EvalLaserArgs) -> Result<(), EvalLaserError> {
    let text = if args.policy {
        let report = crate::laser::policy_eval::evaluate_policy(args)?;
        write_json(args, &report)?;
        crate::laser::policy_eval::render_policy_report(&report)
    } else {
        let report = evaluate_refinement(args)?;
        write_json(args, &report)?;
        render_report(&report)
    };
    print!("{text}");
    Ok(())
}

fn write_json(args: &EvalLaserArgs, report: &impl Serialize) -> Result<(), EvalLaserError> {
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(report)?;
        std::fs::write(path, text + "\n").map_err(|source| EvalLaserError::WriteJson {
            path: path.clone(),
            source,
        })?;
    }
    Ok(())
}

/// The run's worlds, one per seed from `args.seed` on.
pub(crate) fn generate_worlds(
    scenario: &Scenario,
    args: &EvalLaserArgs,
) -> Result<Vec<World>, EvalLaserError> {
    (0..u64::from(args.worlds))
        .map(|k| {
            let seed = args.seed + k;
            World::generate(scenario, seed).map_err(|source| EvalLaserError::World { seed, source })
        })
        .collect()
}

/// The scan service and a simulated ALACS unit (default device settings) showing the first of
/// `worlds`.
pub(crate) fn simulated_alacs(
    worlds: &[World],
) -> Result<(ScanService, LocalAlacsUnit<'_>), EvalLaserError> {
    let service = ScanService::new(
        AlacsDeviceConfig::default().extrinsics,
        alacs_camera_intrinsics(),
        ALACS_FROM_TOF_CAMERA,
    )?;
    let server = AlacsDeviceServer::new(AlacsDeviceConfig::default())?;
    let Some(first_world) = worlds.first() else {
        return Err(EvalLaserError::InvalidArgument {
            name: "worlds",
            value: "0".into(),
            reason: "at least one world is needed",
        });
    };
    Ok((service, LocalAlacsUnit::new(server, first_world)))
}

/// Runs the evaluation (prints nothing).
pub fn evaluate_refinement(args: &EvalLaserArgs) -> Result<RefinementReport, EvalLaserError> {
    check_args(args)?;
    let scenario = load_scenario(&args.scenario).map_err(|source| EvalLaserError::Scenario {
        scenario: args.scenario.clone(),
        source: Box::new(source),
    })?;
    let worlds = generate_worlds(&scenario, args)?;
    let timing = TimingModel {
        slide_speed_m_s: args.slide_speed_m_s,
        settle_ms: args.settle_ms,
        capture_ms: args.capture_ms,
    };
    let mut tof = TofPath::new(&scenario, args.estimator)?;
    let (mut service, mut unit) = simulated_alacs(&worlds)?;
    let mut records = Vec::new();
    let mut apples_generated = 0;
    for (frame_seq, world) in worlds.iter().enumerate() {
        unit.set_world(world);
        apples_generated += world.apples().len();
        let color_from_robot = tof.robot_from_color.inverse();
        let estimates = tof.localise(world, frame_seq as u64)?;
        let estimates = estimates.to_vec();
        for (estimate_index, apple_index) in pair_with_truth(world, &estimates) {
            let estimate = estimates[estimate_index];
            let apple = &world.apples()[apple_index];
            let truth_in_tof = color_from_robot.apply(apple.center_in_robot_m);
            let request = LaserScanRequest {
                request_seq: records.len() as u32 + 1,
                apple_id: apple_index as u32,
                rough_position_in_camera_m: estimate.position_in_camera_m,
                rough_radius_m: estimate.radius_m,
                ..LaserScanRequest::default()
            };
            let mut result = LaserScanResult::default();
            // A failure is in `result.status`; its detail is not needed here.
            let selected_in_alacs = service
                .answer(&mut unit, &request, &mut result, &mut || {})
                .ok()
                .and_then(|scan| {
                    scan.candidates[scan.selected]
                        .as_ref()
                        .ok()
                        .map(|candidate| candidate.centre_in_camera_m)
                });
            let fused = service.last_fusion().copied();
            let motion = service.last_motion();
            let scan_ms = result.scan_duration_ns as f64 * 1e-6;
            let simulator_ms = motion.device_ns as f64 * 1e-6;
            let processing_ms = (scan_ms - simulator_ms).max(0.0);
            let modelled_scan_ms = 1e3 * motion.slide_travel_m / timing.slide_speed_m_s
                + motion.moves as f64 * timing.settle_ms
                + motion.captures as f64 * timing.capture_ms
                + processing_ms;
            let axis_error = |estimate_in_tof: [f64; 3]| {
                let a = ALACS_FROM_TOF_CAMERA.apply(estimate_in_tof);
                let b = ALACS_FROM_TOF_CAMERA.apply(truth_in_tof);
                std::array::from_fn(|k| 1e3 * (a[k] - b[k]).abs())
            };
            let refined = result.status == LaserScanStatus::Ok;
            records.push(AppleRecord {
                world_seed: world.seed(),
                apple_index: apple_index as u32,
                status: result.status,
                distance_m: norm(ALACS_FROM_TOF_CAMERA.apply(truth_in_tof)),
                radius_error_mm: 1e3 * (estimate.radius_m - apple.radius_m),
                error_before_mm: 1e3 * distance(estimate.position_in_camera_m, truth_in_tof),
                error_after_mm: refined
                    .then(|| 1e3 * distance(result.position_in_camera_m, truth_in_tof)),
                selected_error_mm: selected_in_alacs.map(|centre| {
                    1e3 * distance(centre, ALACS_FROM_TOF_CAMERA.apply(truth_in_tof))
                }),
                fused_radius_error_mm: fused.map(|f| 1e3 * (f.radius_m - apple.radius_m)),
                axis_error_before_mm: axis_error(estimate.position_in_camera_m),
                axis_error_after_mm: if refined {
                    axis_error(result.position_in_camera_m)
                } else {
                    [0.0; 3]
                },
                candidates: result.candidate_count,
                slide_travel_mm: 1e3 * motion.slide_travel_m,
                moves: motion.moves,
                captures: motion.captures,
                processing_ms,
                modelled_scan_ms,
                simulator_ms,
            });
            tracing::debug!(record = ?records.last(), "apple evaluated");
        }
    }
    Ok(summarise(args, timing, apples_generated, records))
}

pub(crate) fn check_args(args: &EvalLaserArgs) -> Result<(), EvalLaserError> {
    let invalid = |name, value: String, reason| {
        Err(EvalLaserError::InvalidArgument {
            name,
            value,
            reason,
        })
    };
    if args.worlds == 0 {
        return invalid("worlds", "0".into(), "at least one world is needed");
    }
    if args.seed.checked_add(u64::from(args.worlds)).is_none() {
        return invalid("seed", args.seed.to_string(), "seed + worlds overflows u64");
    }
    if !(args.slide_speed_m_s.is_finite() && args.slide_speed_m_s > 0.0) {
        return invalid(
            "slide-speed-m-s",
            args.slide_speed_m_s.to_string(),
            "must be a positive speed",
        );
    }
    for (name, value) in [
        ("settle-ms", args.settle_ms),
        ("capture-ms", args.capture_ms),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return invalid(name, value.to_string(), "must be a non-negative time");
        }
    }
    for (name, value) in [
        ("duration-s", args.duration_s),
        ("frame-interval-ms", args.frame_interval_ms),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return invalid(name, value.to_string(), "must be a positive time");
        }
    }
    if args.duration_s * 1e3 / args.frame_interval_ms > 1e5 {
        return invalid(
            "duration-s",
            args.duration_s.to_string(),
            "more than 100000 frames per world",
        );
    }
    Ok(())
}

/// The ToF camera and perception, as the stack runs them.
pub(crate) struct TofPath {
    renderer: RgbdRenderer,
    pub(crate) perception: Perception,
    pub(crate) robot_from_color: RigidTransform,
    rgb: Vec<u8>,
    depth_mm: Vec<u16>,
    estimates: Vec<AppleEstimate>,
}

impl TofPath {
    pub(crate) fn new(
        scenario: &Scenario,
        estimator: EstimatorKind,
    ) -> Result<Self, EvalLaserError> {
        let renderer = RgbdRenderer::new(&scenario.camera)?;
        let robot_from_color = renderer.robot_from_color();
        let cameras = CameraSetup {
            color: *renderer.color_intrinsics(),
            depth: *renderer.depth_intrinsics(),
            color_from_depth: robot_from_color
                .inverse()
                .compose(&renderer.robot_from_depth()),
            robot_from_camera: robot_from_color,
        };
        let mut config = PerceptionConfig::default();
        config.estimator.kind = estimator;
        Ok(Self {
            perception: Perception::new(config, cameras)?,
            renderer,
            robot_from_color,
            rgb: vec![0; RGB_BYTES],
            depth_mm: vec![0; DEPTH_PIXELS],
            estimates: Vec::new(),
        })
    }

    /// Renders the ToF frame of `world` and localises its apples (colour-camera frame).
    pub(crate) fn localise(
        &mut self,
        world: &World,
        frame_seq: u64,
    ) -> Result<&[AppleEstimate], EvalLaserError> {
        self.renderer.render_color(world, &mut self.rgb)?;
        self.renderer
            .render_depth(world, frame_seq, &mut self.depth_mm)?;
        let color = self.renderer.color_intrinsics();
        let depth = self.renderer.depth_intrinsics();
        let rgb = RgbView {
            width_px: color.width_px,
            height_px: color.height_px,
            data: &self.rgb,
        };
        let depth = DepthView {
            width_px: depth.width_px,
            height_px: depth.height_px,
            data: &self.depth_mm,
        };
        self.perception
            .process_into(&rgb, &depth, &mut self.estimates);
        Ok(&self.estimates)
    }
}

/// Pairs estimates with true apples on the tree: centres within [`MATCH_RADII`] true radii
/// (robot frame), one to one, nearest pairs first. Returns `(estimate index, apple index)` in
/// estimate order.
pub(crate) fn pair_with_truth(world: &World, estimates: &[AppleEstimate]) -> Vec<(usize, usize)> {
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for (e, estimate) in estimates.iter().enumerate() {
        for (a, apple) in world.apples().iter().enumerate() {
            if apple.state != AppleState::OnTree {
                continue;
            }
            let d = distance(estimate.position_in_robot_m, apple.center_in_robot_m);
            if d <= MATCH_RADII * apple.radius_m {
                pairs.push((d, e, a));
            }
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut used_estimates = vec![false; estimates.len()];
    let mut used_apples = vec![false; world.apples().len()];
    let mut paired = Vec::new();
    for (_, e, a) in pairs {
        if used_estimates[e] || used_apples[a] {
            continue;
        }
        used_estimates[e] = true;
        used_apples[a] = true;
        paired.push((e, a));
    }
    // Scan in perception's order, as a harvest cycle would ask.
    paired.sort_unstable();
    paired
}

fn summarise(
    args: &EvalLaserArgs,
    timing: TimingModel,
    apples_generated: usize,
    apples: Vec<AppleRecord>,
) -> RefinementReport {
    let refined: Vec<&AppleRecord> = apples
        .iter()
        .filter(|r| r.status == LaserScanStatus::Ok)
        .collect();
    let count_status =
        |status: LaserScanStatus| apples.iter().filter(|r| r.status == status).count();
    let scanned = || apples.iter().filter(|r| r.captures > 0);
    let mean_axis = |axis: fn(&AppleRecord) -> [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|k| Summary::of(refined.iter().map(|r| axis(r)[k])).mean)
    };
    let max_axis: [f64; 3] =
        std::array::from_fn(|k| Summary::of(refined.iter().map(|r| r.axis_error_after_mm[k])).max);
    RefinementReport {
        scenario: args.scenario.clone(),
        first_seed: args.seed,
        worlds: args.worlds,
        estimator: args.estimator.name().to_owned(),
        timing,
        apples_generated,
        apples_paired: apples.len(),
        refined: refined.len(),
        no_laser_line: count_status(LaserScanStatus::NoLaserLine),
        out_of_reach: count_status(LaserScanStatus::OutOfReach),
        device_errors: count_status(LaserScanStatus::DeviceError),
        tof_error_all_mm: Summary::of(apples.iter().map(|r| r.error_before_mm)),
        tof_error_mm: Summary::of(refined.iter().map(|r| r.error_before_mm)),
        laser_error_mm: Summary::of(refined.iter().filter_map(|r| r.error_after_mm)),
        selected_candidate_error_mm: Summary::of(
            refined.iter().filter_map(|r| r.selected_error_mm),
        ),
        fused: refined
            .iter()
            .filter(|r| r.fused_radius_error_mm.is_some())
            .count(),
        laser_error_fused_mm: Summary::of(
            refined
                .iter()
                .filter(|r| r.fused_radius_error_mm.is_some())
                .filter_map(|r| r.error_after_mm),
        ),
        laser_error_unfused_mm: Summary::of(
            refined
                .iter()
                .filter(|r| r.fused_radius_error_mm.is_none())
                .filter_map(|r| r.error_after_mm),
        ),
        tof_radius_error_mm: Summary::of(
            refined
                .iter()
                .filter(|r| r.fused_radius_error_mm.is_some())
                .map(|r| r.radius_error_mm.abs()),
        ),
        fused_radius_error_mm: Summary::of(
            refined
                .iter()
                .filter_map(|r| r.fused_radius_error_mm.map(f64::abs)),
        ),
        tof_mean_axis_error_mm: mean_axis(|r| r.axis_error_before_mm),
        laser_mean_axis_error_mm: mean_axis(|r| r.axis_error_after_mm),
        laser_max_axis_error_mm: max_axis,
        improved: refined
            .iter()
            .filter(|r| {
                r.error_after_mm
                    .is_some_and(|after| after < r.error_before_mm)
            })
            .count(),
        within_paper_bounds: refined
            .iter()
            .filter(|r| (0..3).all(|k| r.axis_error_after_mm[k] <= PAPER_MAX_ERROR_MM[k]))
            .count(),
        modelled_scan_ms: Summary::of(scanned().map(|r| r.modelled_scan_ms)),
        processing_ms: Summary::of(scanned().map(|r| r.processing_ms)),
        slide_travel_mm: Summary::of(scanned().map(|r| r.slide_travel_mm)),
        simulator_ms: Summary::of(scanned().map(|r| r.simulator_ms)),
        apples,
    }
}

/// The report as readable text.
pub fn render_report(report: &RefinementReport) -> String {
    let mut out = String::new();
    let t = &report.timing;
    // Writing into a String cannot fail.
    let _ = writeln!(
        out,
        "Laser refinement: scenario `{}`, {} worlds (seeds {}..{}), ToF estimator {}.\n\
         {} apples generated, {} paired with a ToF estimate (within {MATCH_RADII} radii): \
         {} refined, {} no laser line, {} out of view/reach, {} device errors.\n",
        report.scenario,
        report.worlds,
        report.first_seed,
        report.first_seed + u64::from(report.worlds.max(1)) - 1,
        report.estimator,
        report.apples_generated,
        report.apples_paired,
        report.refined,
        report.no_laser_line,
        report.out_of_reach,
        report.device_errors,
    );
    write_summary_table(
        &mut out,
        "3D error, mm                       ",
        &[
            ("ToF, all paired apples        ", &report.tof_error_all_mm),
            ("ToF, refined apples           ", &report.tof_error_mm),
            ("laser answer, refined apples  ", &report.laser_error_mm),
            (
                "  fused sphere (>= 3 circles) ",
                &report.laser_error_fused_mm,
            ),
            (
                "  fewer circles: candidate   ",
                &report.laser_error_unfused_mm,
            ),
            (
                "selected candidate, all      ",
                &report.selected_candidate_error_mm,
            ),
        ],
    );
    let _ = writeln!(
        out,
        "\nThe answer is the fused sphere on {} of {} refined apples. Radius error, mm: ToF {}; \
         scan's fused sphere {}.",
        report.fused,
        report.refined,
        report.tof_radius_error_mm.columns(),
        report.fused_radius_error_mm.columns(),
    );
    let axes = |a: [f64; 3]| format!("{:.2} / {:.2} / {:.2}", a[0], a[1], a[2]);
    let _ = writeln!(
        out,
        "\nALACS-frame errors x / y / z, mm: ToF mean {}; laser mean {}, max {} \
         (paper bounds {}). Laser better than ToF on {} of {}; within the paper's bounds on {}.\n",
        axes(report.tof_mean_axis_error_mm),
        axes(report.laser_mean_axis_error_mm),
        axes(report.laser_max_axis_error_mm),
        axes(PAPER_MAX_ERROR_MM),
        report.improved,
        report.refined,
        report.within_paper_bounds,
    );
    let _ = writeln!(
        out,
        "Scan time model: slide {} m/s, settle {} ms per move, {} ms per image, plus measured \
         processing.",
        t.slide_speed_m_s, t.settle_ms, t.capture_ms
    );
    write_summary_table(
        &mut out,
        "per scan                           ",
        &[
            ("modelled scan time, ms        ", &report.modelled_scan_ms),
            ("  of which processing, ms     ", &report.processing_ms),
            ("slide travel, mm              ", &report.slide_travel_mm),
            ("simulator render (not robot)  ", &report.simulator_ms),
        ],
    );
    out
}

pub(crate) fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_quantiles() {
        let summary = Summary::of([4.0, 1.0, 3.0, 2.0, f64::NAN, 5.0]);
        assert_eq!(summary.count, 5);
        assert!((summary.mean - 3.0).abs() < 1e-12);
        assert_eq!((summary.median, summary.p95, summary.max), (3.0, 5.0, 5.0));
        assert_eq!(Summary::of([]), Summary::default());
    }

    #[test]
    fn arguments_are_checked() {
        let args = EvalLaserArgs {
            scenario: "default".into(),
            seed: 1,
            worlds: 1,
            estimator: EstimatorKind::SphereFit,
            slide_speed_m_s: 0.1,
            settle_ms: 50.0,
            capture_ms: 40.0,
            json: None,
            policy: false,
            perception_config: None,
            duration_s: 12.0,
            frame_interval_ms: 200.0,
        };
        assert!(check_args(&args).is_ok());
        for bad in [
            EvalLaserArgs {
                worlds: 0,
                ..args.clone()
            },
            EvalLaserArgs {
                slide_speed_m_s: 0.0,
                ..args.clone()
            },
            EvalLaserArgs {
                settle_ms: f64::NAN,
                ..args.clone()
            },
            EvalLaserArgs {
                seed: u64::MAX,
                ..args.clone()
            },
            EvalLaserArgs {
                frame_interval_ms: -1.0,
                ..args.clone()
            },
        ] {
            assert!(check_args(&bad).is_err(), "{bad:?}");
        }
    }
}
