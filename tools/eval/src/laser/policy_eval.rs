//! `harvest eval laser --policy`: perception's laser-scan policy as the running stack applies it,
//! measured on simulated orchards.
//!
//! Per seeded world, simulated time advances in camera frames of `--frame-interval-ms` for
//! `--duration-s`. At each frame the ToF camera's frames are rendered (fresh depth noise) and
//! perception's pipeline localizes the apples; [`LaserRefiner`] (the code the perception
//! process runs) follows them over frames, queues scan requests for the apples its policy picks
//! and publishes refined positions for the apples whose scan has finished. The scanner takes one
//! request at a time: the scan is computed at once by
//! [`ScanService`](harvest_laser::service::ScanService) on the simulator's ALACS device, but its answer
//! reaches perception only after the scan's modelled duration (slide travel, settling, capture
//! and measured processing; see [`crate::laser::refinement`]), so the frame loop never waits for it.
//!
//! At the last frame of each world, the published apples are paired with the true apples
//! (within 2 true radii, one to one). Reported: the 3D error of the ToF estimate and of the
//! published position, on the laser-refined apples and on every published apple; how many
//! apples the policy picked and what became of them; the scanner's busy time per world.

use std::fmt::Write as _;

use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult};
use harvest_perception::PerceptionConfig;
use harvest_perception::config_file::read_config;
use harvest_perception::laser_refiner::{LaserRefiner, ScanResultOutcome, TrackedApple};
use harvest_perception::scan_policy::LaserScanConfig;
use harvest_sim::process::load_scenario;
use serde::Serialize;

use crate::laser::refinement::{
    EvalLaserArgs, EvalLaserError, Summary, TofPath, check_args, distance, generate_worlds,
    pair_with_truth, simulated_alacs,
};
use crate::laser::report_table::write_summary_table;

/// The evaluation's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PolicyReport {
    pub scenario: String,
    pub first_seed: u64,
    pub worlds: u32,
    pub estimator: String,
    pub policy: LaserScanConfig,
    pub duration_s: f64,
    pub frame_interval_ms: f64,
    /// Apples published at the last frame of each world and paired with a true apple.
    pub apples_published: usize,
    /// Scans the policy asked for, and what became of them.
    pub scans_requested: u64,
    pub scans_refined: u64,
    pub scans_failed: u64,
    pub scans_refused: u64,
    pub scans_unanswered_at_end: usize,
    /// Answered scans by `LaserScanResult::status`: ok, no laser line, out of the slide's view
    /// or reach, device error.
    pub scan_status_counts: [u64; 4],
    /// Published (paired) apples at the last frames that carry a laser position.
    pub refined_apples: usize,
    /// On those apples: error of this frame's ToF estimate and of the published position, mm.
    pub refined_tof_error_mm: Summary,
    pub refined_published_error_mm: Summary,
    /// Over every published, paired apple: ToF estimate vs published position, mm.
    pub all_tof_error_mm: Summary,
    pub all_published_error_mm: Summary,
    /// Apples the policy would still ask for at the end (qualifying, never asked).
    pub waiting_at_end: usize,
    /// Scanner time per world (sum of the modelled durations of its scans), s.
    pub scanner_busy_s: Summary,
    /// Modelled duration of one scan, ms.
    pub scan_ms: Summary,
    /// CPU time of the refiner's per-frame work (association, policy), microseconds.
    pub refiner_update_us: Summary,
}

/// A scan on its way: computed, answered after its modelled duration.
struct InFlight {
    result: LaserScanResult,
    answer_at_ns: u64,
}

/// Runs the evaluation (prints nothing).
pub fn evaluate_policy(args: &EvalLaserArgs) -> Result<PolicyReport, EvalLaserError> {
    check_args(args)?;
    let scenario = load_scenario(&args.scenario).map_err(|source| EvalLaserError::Scenario {
        scenario: args.scenario.clone(),
        source: Box::new(source),
    })?;
    let mut perception_config = match &args.perception_config {
        Some(path) => read_config(path).map_err(|source| EvalLaserError::InvalidArgument {
            name: "perception-config",
            value: format!("{}: {source}", path.display()),
            reason: "unreadable perception config",
        })?,
        None => PerceptionConfig::default(),
    };
    perception_config.estimator.kind = args.estimator;
    let policy = perception_config.laser;
    policy
        .validate()
        .map_err(|error| EvalLaserError::InvalidArgument {
            name: "perception-config",
            value: error.to_string(),
            reason: "invalid laser policy",
        })?;
    let mut tof = TofPath::new(&scenario, args.estimator)?;
    let color = tof.perception.cameras().color;
    let color_focal_px = 0.5 * (color.fx_px + color.fy_px);
    let robot_from_color = tof.robot_from_color;
    let worlds = generate_worlds(&scenario, args)?;
    let (mut service, mut unit) = simulated_alacs(&worlds)?;
    let frame_ns = (args.frame_interval_ms * 1e6) as u64;
    let frames = ((args.duration_s * 1e9) as u64 / frame_ns.max(1)).max(1);

    let mut report = PolicyReport {
        scenario: args.scenario.clone(),
        first_seed: args.seed,
        worlds: args.worlds,
        estimator: format!("{:?}", args.estimator),
        policy,
        duration_s: args.duration_s,
        frame_interval_ms: args.frame_interval_ms,
        apples_published: 0,
        scans_requested: 0,
        scans_refined: 0,
        scans_failed: 0,
        scans_refused: 0,
        scans_unanswered_at_end: 0,
        scan_status_counts: [0; 4],
        refined_apples: 0,
        refined_tof_error_mm: Summary::default(),
        refined_published_error_mm: Summary::default(),
        all_tof_error_mm: Summary::default(),
        all_published_error_mm: Summary::default(),
        waiting_at_end: 0,
        scanner_busy_s: Summary::default(),
        scan_ms: Summary::default(),
        refiner_update_us: Summary::default(),
    };
    let (mut refined_tof, mut refined_published) = (Vec::new(), Vec::new());
    let (mut all_tof, mut all_published) = (Vec::new(), Vec::new());
    let (mut busy_s, mut scan_ms, mut update_us) = (Vec::new(), Vec::new(), Vec::new());
    let mut tracked: Vec<TrackedApple> = Vec::new();
    let mut queue: Vec<LaserScanRequest> = Vec::new();
    let mut frame_seq = 0_u64;
    for world in &worlds {
        let seed = world.seed();
        unit.set_world(world);
        let mut refiner = LaserRefiner::new(policy);
        let mut in_flight: Option<InFlight> = None;
        queue.clear();
        let mut world_busy_ms = 0.0;
        for frame in 0..frames {
            let now_ns = frame * frame_ns;
            if in_flight
                .as_ref()
                .is_some_and(|scan| scan.answer_at_ns <= now_ns)
                && let Some(scan) = in_flight.take()
            {
                if let Some(count) = report
                    .scan_status_counts
                    .get_mut(usize::from(scan.result.status.raw()))
                {
                    *count += 1;
                }
                match refiner.handle_result(&scan.result, &robot_from_color) {
                    ScanResultOutcome::Refined => report.scans_refined += 1,
                    ScanResultOutcome::ScanFailed => report.scans_failed += 1,
                    ScanResultOutcome::Refused => report.scans_refused += 1,
                    ScanResultOutcome::Unmatched => {}
                }
            }
            let estimates = tof.localise(world, frame_seq)?.to_vec();
            frame_seq += 1;
            let started = std::time::Instant::now();
            refiner.update(&estimates, color_focal_px, now_ns, &mut tracked);
            update_us.push(started.elapsed().as_secs_f64() * 1e6);
            queue.extend_from_slice(refiner.requests());
            report.scans_requested += refiner.requests().len() as u64;
            if in_flight.is_none() && !queue.is_empty() {
                let request = queue.remove(0);
                let mut result = LaserScanResult::default();
                // A failure is in `result.status`.
                let _ = service.answer(&mut unit, &request, &mut result, &mut || {});
                let motion = service.last_motion();
                let processing_ms = (result.scan_duration_ns as f64 * 1e-6
                    - motion.device_ns as f64 * 1e-6)
                    .max(0.0);
                let duration_ms = 1e3 * motion.slide_travel_m / args.slide_speed_m_s
                    + motion.moves as f64 * args.settle_ms
                    + motion.captures as f64 * args.capture_ms
                    + processing_ms;
                world_busy_ms += duration_ms;
                if motion.captures > 0 {
                    scan_ms.push(duration_ms);
                }
                in_flight = Some(InFlight {
                    result,
                    answer_at_ns: now_ns + (duration_ms * 1e6) as u64,
                });
            }
            if frame + 1 == frames {
                report.scans_unanswered_at_end += queue.len() + usize::from(in_flight.is_some());
                report.waiting_at_end +=
                    count_waiting(&refiner, &estimates, &tracked, color_focal_px);
                let color_from_robot = robot_from_color.inverse();
                for (e, a) in pair_with_truth(world, &estimates) {
                    let truth_in_camera =
                        color_from_robot.apply(world.apples()[a].center_in_robot_m);
                    let estimate = &estimates[e];
                    let tof_mm = 1e3 * distance(estimate.position_in_camera_m, truth_in_camera);
                    let published_mm = match tracked.get(e).and_then(|t| t.laser_position_m) {
                        Some((camera, _)) => {
                            let published = 1e3 * distance(camera, truth_in_camera);
                            refined_tof.push(tof_mm);
                            refined_published.push(published);
                            published
                        }
                        None => tof_mm,
                    };
                    all_tof.push(tof_mm);
                    all_published.push(published_mm);
                }
            }
        }
        busy_s.push(world_busy_ms * 1e-3);
        tracing::debug!(seed, busy_ms = world_busy_ms, stats = ?refiner.stats(), "world done");
    }
    report.apples_published = all_tof.len();
    report.refined_apples = refined_tof.len();
    report.refined_tof_error_mm = Summary::of(refined_tof);
    report.refined_published_error_mm = Summary::of(refined_published);
    report.all_tof_error_mm = Summary::of(all_tof);
    report.all_published_error_mm = Summary::of(all_published);
    report.scanner_busy_s = Summary::of(busy_s);
    report.scan_ms = Summary::of(scan_ms);
    report.refiner_update_us = Summary::of(update_us);
    Ok(report)
}

/// Apples of the last frame that qualify for a scan but were never asked for.
fn count_waiting(
    refiner: &LaserRefiner,
    estimates: &[harvest_perception::AppleEstimate],
    tracked: &[TrackedApple],
    color_focal_px: f64,
) -> usize {
    let config = refiner.config();
    estimates
        .iter()
        .zip(tracked)
        .filter(|(estimate, apple)| {
            let never_asked = refiner.tracks().tracks().iter().any(|track| {
                track.id == apple.apple_id
                    && track.scan == harvest_perception::apple_tracks::ScanState::NotRequested
            });
            let evidence = harvest_perception::scan_policy::ScanEvidence {
                visible_fraction: harvest_perception::estimate_checks::visible_fraction(
                    estimate.visible_px,
                    estimate.radius_m,
                    estimate.position_in_camera_m[2],
                    color_focal_px,
                ),
                position_confidence: estimate.position_confidence,
                fallback: estimate.fallback,
            };
            never_asked && config.scan_priority(&evidence).is_some()
        })
        .count()
}

/// The report as readable text.
pub fn render_policy_report(report: &PolicyReport) -> String {
    let mut out = String::new();
    let p = &report.policy;
    // Writing into a String cannot fail.
    let _ = writeln!(
        out,
        "Laser refinement by perception's scan policy: scenario `{}`, {} worlds (seeds {}..{}), \
         ToF estimator {}, {} s per world at one frame per {} ms.\n\
         Policy: enabled {}, scan when visible fraction < {} or position confidence < {}{}; \
         {} per frame, {} pending at most.\n",
        report.scenario,
        report.worlds,
        report.first_seed,
        report.first_seed + u64::from(report.worlds.max(1)) - 1,
        report.estimator,
        report.duration_s,
        report.frame_interval_ms,
        p.enabled,
        p.max_visible_fraction,
        p.min_position_confidence,
        if p.scan_fallback_estimates {
            " or a fallback estimate"
        } else {
            ""
        },
        p.max_scans_per_frame,
        p.max_pending_scans,
    );
    let _ = writeln!(
        out,
        "Scans asked for: {}; refined {}, failed {} (no laser line {}, out of the slide's view or \
         reach {}, device error {}), refused by perception (one image's candidate, or too far \
         from the ToF estimate) {}, unanswered at \
         the end {}. Qualifying apples never asked for at the end: {}.\n",
        report.scans_requested,
        report.scans_refined,
        report.scans_failed,
        report.scan_status_counts[1],
        report.scan_status_counts[2],
        report.scan_status_counts[3],
        report.scans_refused,
        report.scans_unanswered_at_end,
        report.waiting_at_end,
    );
    write_summary_table(
        &mut out,
        "3D error at each world's last frame, mm            ",
        &[
            (
                "laser-refined apples: ToF estimate            ",
                &report.refined_tof_error_mm,
            ),
            (
                "laser-refined apples: published (laser)       ",
                &report.refined_published_error_mm,
            ),
            (
                "all published apples: ToF only                ",
                &report.all_tof_error_mm,
            ),
            (
                "all published apples: with the scans          ",
                &report.all_published_error_mm,
            ),
        ],
    );
    write_summary_table(
        &mut out,
        "\nCost                                               ",
        &[
            (
                "scanner busy per world, s                     ",
                &report.scanner_busy_s,
            ),
            (
                "one scan that ran the slide (modelled), ms    ",
                &report.scan_ms,
            ),
            (
                "refiner per frame (perception CPU), us        ",
                &report.refiner_update_us,
            ),
        ],
    );
    out
}
