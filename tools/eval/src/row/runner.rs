//! One row, stop by stop, on the simulated clock.
//!
//! Per 5 ms control period, in this order:
//! 1. a detection set is captured when the stop cycle needs one ([`DetectionLoop`]) and handed
//!    to the episode, delivered after the simulated perception latency;
//! 2. the stop cycle ([`harvest_field::StopCycle`], the executive's own sequencer) ticks on
//!    what the stack shows (trailer and platform positions, arms parked or holding, the
//!    newest delivered set, each `HarvestComplete` of the vacuum supervisor as
//!    `on_harvest_complete`, as the executive's row work feeds it);
//!    its platform moves and tractor advances go to the simulated stages and tractor
//!    (`harvest_sim`'s `PlatformStages`, `TractorMotion`, the devices `harvest sim` serves);
//! 3. `operator/mode` is published: harvesting, with the `field_hold` while the cycle
//!    repositions and a disabled arm's `arms_enabled` off (the executive's mode; the nodes obey
//!    it by the one rule);
//! 4. the harvesting episode ([`crate::harvest::Episode`]: both arms' and the vacuum
//!    supervisor's nodes under the robot's tick on the simulated robot) steps one period;
//! 5. the stages and the tractor step, and the world moves with the robot
//!    (`World::set_robot_offset_m`, as `harvest sim`'s physics thread does);
//! 6. assignments and ended attempts feed the stop cycle.
//!
//! Ground truth is taken when a stop starts harvesting (platform positioned, fresh set): the
//! apples in reach there, and at the fixed platform position ([`super::truth`]).

use std::collections::BTreeSet;

use harvest_arm::node::ArmNodeConfig;
use harvest_field::{
    FieldAction, FieldView, RowReport, StageTravel, StopCycle, StopCycleConfig, StopPhase,
    StopReport,
};
use harvest_ipc::payloads::ArmPhase as PhaseCode;
use harvest_ipc::payloads::{OperatorModeCode, OperatorModeState};
use harvest_robot_model::params::ArmParams;
use harvest_sim::World;
use harvest_sim::platform_device::{PlatformDeviceConfig, PlatformStages};
use harvest_sim::robot::{SimRobot, SimRobotConfig};
use harvest_sim::row::RowScenario;
use harvest_sim::tractor_device::TractorMotion;
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::PressureConfig;
use serde::Serialize;

use super::args::DetectionsArg;
use super::error::RowEvalError;
use super::perception_loop::{DetectionLoop, FrameNeed, FramePolicy};
use super::truth::reachable_apples;
use crate::harvest::runner::CONTROL_PERIOD_NS;
use crate::harvest::{DetectionFeed, Episode, EpisodeConfig, EpisodeOutcome, ModeFeed};

/// Fallback distance between stops of a one-section row, m (never travelled).
const ONE_STOP_SPACING_M: f64 = 2.0;
/// A platform move or tractor advance not done after this long is sent again (the
/// executive's value), ns.
const RESEND_NS: u64 = 10_000_000_000;

/// What to run.
#[derive(Debug, Clone)]
pub struct RowRunConfig {
    /// Short name of the row (report).
    pub name: String,
    /// The row, with the timing profile applied to its sections' scenarios.
    pub row: RowScenario,
    pub seed: u64,
    /// 1: arm 1 alone; 2: both.
    pub arms: u8,
    pub policy: PolicyKind,
    pub arm_node: ArmNodeConfig,
    pub pressure: PressureConfig,
    pub detections: DetectionsArg,
    pub frames: FramePolicy,
    /// The stop cycle's quiet time, ns.
    pub quiet_ns: u64,
    /// Simulated time limit, s.
    pub max_row_s: f64,
}

/// One stop's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StopFigures {
    /// The stop cycle's own report (counts from detections: detected before positioning, in
    /// reach before, predicted, after positioning, out of reach; the chosen offsets).
    #[serde(flatten)]
    pub cycle: StopReport,
    /// Ground truth when harvesting began: apples on the tree in reach with the chosen offsets,
    /// and with the platform at its fixed position (stages at 0).
    pub truth_reachable_chosen: usize,
    pub truth_reachable_fixed: usize,
    /// Attempts dispatched while the stop harvested, and those that harvested.
    pub attempts: u32,
    pub harvested: u32,
    /// From the first fresh set after positioning to the stop done, s.
    pub harvest_s: f64,
    /// From arrival to the stop done (parking, positioning, settling, harvesting), s.
    pub stop_s: f64,
}

/// What one row run produced.
#[derive(Debug)]
pub struct RowOutcome {
    pub name: String,
    pub seed: u64,
    pub arms: u8,
    /// Apples in the row's world (ground truth).
    pub apples_on_row: usize,
    /// Apples in reach (ground truth) at some stop with the chosen offsets.
    pub reachable: BTreeSet<u32>,
    pub stops: Vec<StopFigures>,
    /// The stop cycle's row report (None when the time limit cut the row).
    pub row_report: Option<RowReport>,
    /// First arrival to the last stop done, s (travel and positioning included).
    pub row_s: f64,
    /// Frames processed by perception (or model sets).
    pub frames: u64,
    /// The harvesting episode: attempts, apples, safety.
    pub episode: EpisodeOutcome,
    /// The final world (apple states, flags).
    pub world: World,
}

impl RowOutcome {
    /// Apples on the dropping module at the end.
    pub fn harvested(&self) -> usize {
        self.world
            .apples()
            .iter()
            .filter(|a| a.state == harvest_sim::AppleState::Harvested)
            .count()
    }
}

/// Stops and spacing of a row: one stop per section, at the sections' mean spacing.
fn stops_of(row: &RowScenario) -> (u32, f64) {
    let sections = &row.file.sections;
    let stops = sections.len() as u32;
    let spacing_m = match (sections.first(), sections.last()) {
        (Some(first), Some(last)) if stops > 1 => {
            (last.center_m - first.center_m) / f64::from(stops - 1)
        }
        _ => ONE_STOP_SPACING_M,
    };
    (stops, spacing_m)
}

/// Runs one row.
pub fn run_row(config: &RowRunConfig) -> Result<RowOutcome, RowEvalError> {
    let row = &config.row;
    let mut world =
        World::generate_row(row, config.seed).map_err(|source| RowEvalError::World {
            row: config.name.clone(),
            seed: config.seed,
            source: Box::new(source),
        })?;
    let apples_on_row = world.apples().len();
    let tractor_row = row.file.tractor;
    let row_platform = row.file.platform;
    let row_end_m = world.scenario().canopy.y_range_m[1].max(tractor_row.start_m);
    let offset = |stage_m: [f64; 2], trailer_m: f64| {
        let [x, z] = row_platform.offset_m(stage_m);
        [x, trailer_m, z]
    };
    world.set_robot_offset_m(offset([0.0; 2], tractor_row.start_m));
    let mut platform = PlatformStages::new(PlatformDeviceConfig {
        travel: row_platform.travel(),
        ..PlatformDeviceConfig::default()
    })?;
    let mut tractor = TractorMotion::new(tractor_row.speed_m_per_s, tractor_row.start_m, row_end_m);
    let (stops, stop_spacing_m) = stops_of(row);
    let travel = row_platform.travel();
    let mut cycle = StopCycle::new(
        StopCycleConfig {
            stops,
            stop_spacing_m,
            auto_advance: true,
            travel: StageTravel {
                in_out_max_m: travel.in_out_max_m,
                up_down_max_m: travel.up_down_max_m,
            },
            quiet_ns: config.quiet_ns,
            resend_ns: RESEND_NS,
        },
        [ArmParams::arm1(), ArmParams::arm2()],
    )?;
    let mut detections = match config.detections {
        DetectionsArg::Perception => DetectionLoop::perception(&world, config.frames)?,
        DetectionsArg::Model => DetectionLoop::model(config.seed, config.frames),
    };
    let mut episode_config = EpisodeConfig::new(
        world.scenario().clone(),
        config.policy,
        config.arms,
        config.seed,
    );
    episode_config.max_episode_s = config.max_row_s;
    episode_config.arm_node = config.arm_node;
    episode_config.pressure = config.pressure;
    episode_config.detection_feed = DetectionFeed::External;
    episode_config.mode_feed = ModeFeed::External;
    episode_config.keep_events = false;
    let robot = SimRobot::from_world(world, SimRobotConfig::default())
        .map_err(crate::harvest::HarvestEvalError::from)?;
    let mut episode = Episode::with_robot(episode_config, robot)?;

    let start_ns = episode.now_ns();
    let max_ns = start_ns + (config.max_row_s * 1e9) as u64;
    let period_s = CONTROL_PERIOD_NS as f64 * 1e-9;
    let mut pending: Vec<(u64, u64, Vec<[f64; 3]>)> = Vec::new();
    let mut view_detections: Option<(u64, Vec<[f64; 3]>)> = None;
    let mut stops_out: Vec<StopFigures> = Vec::new();
    let mut reachable = BTreeSet::new();
    let mut harvest_started_ns: Option<u64> = None;
    let mut truth_at_start = (0usize, 0usize);
    let mut seen_attempts = 0usize;
    let mut ended: BTreeSet<(u8, u64)> = BTreeSet::new();
    let mut last_end_ns = 0u64;
    let mut row_report = None;
    let mut truncated = false;
    loop {
        let now_ns = episode.now_ns();
        if now_ns >= max_ns {
            truncated = true;
            break;
        }
        // 1. Detections.
        let phase = cycle.phase();
        let need = match phase {
            StopPhase::Parking { since_ns } | StopPhase::Settling { since_ns } => {
                FrameNeed::After(since_ns)
            }
            StopPhase::Harvesting { .. } => FrameNeed::Harvesting,
            _ => FrameNeed::None,
        };
        let ended_since = detections
            .last_capture_ns()
            .is_none_or(|last| last_end_ns > last);
        if detections.due(now_ns, need, ended_since) {
            let (deliver_ns, set) = {
                let robot = episode.robot().borrow();
                detections.capture(robot.world(), now_ns)?
            };
            let apples = set.apples.iter().map(|a| a.position_in_robot_m).collect();
            pending.push((deliver_ns, now_ns, apples));
            episode.deliver(deliver_ns, set);
        }
        if let Some(k) = pending.iter().position(|(at, _, _)| *at <= now_ns) {
            let (_, capture_ns, apples) = pending.remove(k);
            view_detections = Some((capture_ns, apples));
        }

        // 2. The stop cycle.
        let states = *episode.arm_states();
        let parked = states
            .iter()
            .all(|s| s.is_some_and(|s| s.phase == PhaseCode::Idle && s.holding == 0));
        let holding = states.iter().flatten().any(|s| s.holding != 0);
        if episode.completed_last_tick() {
            cycle.on_harvest_complete(now_ns);
        }
        let view = FieldView {
            tractor: Some((tractor.position_m(), tractor.in_motion())),
            platform: Some((platform.position_m(), platform.in_motion())),
            arms_parked: parked,
            arms_holding: holding,
            detections: view_detections.clone(),
        };
        let actions = cycle.tick(now_ns, &view);
        let t_s = Episode::t_s(now_ns);
        if matches!(phase, StopPhase::Settling { .. })
            && matches!(cycle.phase(), StopPhase::Harvesting { .. })
        {
            harvest_started_ns = Some(now_ns);
            let robot = episode.robot().borrow();
            let at = platform.position_m();
            let chosen = reachable_apples(robot.world(), config.arms, [0.0; 3], &config.arm_node);
            let fixed = reachable_apples(
                robot.world(),
                config.arms,
                [-at[0], 0.0, -at[1]],
                &config.arm_node,
            );
            truth_at_start = (chosen.len(), fixed.len());
            reachable.extend(chosen);
        }
        for action in actions {
            match action {
                FieldAction::MovePlatform { target_m } => {
                    if !platform.apply(false, target_m, now_ns) {
                        return Err(RowEvalError::Refused {
                            device: "platform",
                            what: format!("target {target_m:?} m"),
                            t_s,
                        });
                    }
                }
                FieldAction::AdvanceTractor { distance_m } => {
                    let target_m = tractor.position_m() + distance_m;
                    if !tractor.apply(false, target_m, now_ns) {
                        return Err(RowEvalError::Refused {
                            device: "tractor",
                            what: format!("advance to {target_m:.3} m"),
                            t_s,
                        });
                    }
                }
                FieldAction::StopFinished(report) => {
                    let from_s = harvest_started_ns.map_or(t_s, Episode::t_s);
                    let (attempts, harvested) = episode
                        .recorder()
                        .attempts
                        .iter()
                        .filter(|a| a.dispatched_s >= from_s && a.dispatched_s <= t_s)
                        .fold((0, 0), |(n, ok), a| (n + 1, ok + u32::from(a.harvested)));
                    tracing::info!(
                        row = %config.name,
                        stop = report.stop,
                        attempts,
                        harvested,
                        "stop finished"
                    );
                    stops_out.push(StopFigures {
                        truth_reachable_chosen: truth_at_start.0,
                        truth_reachable_fixed: truth_at_start.1,
                        attempts,
                        harvested,
                        harvest_s: t_s - from_s,
                        stop_s: report.duration_ns as f64 * 1e-9,
                        cycle: report,
                    });
                    harvest_started_ns = None;
                    truth_at_start = (0, 0);
                }
                FieldAction::RowFinished(report) => row_report = Some(report),
            }
        }
        if row_report.is_some() {
            break;
        }

        // 3.-4. Hold while repositioning; the harvest.
        let mode = OperatorModeState {
            mode: OperatorModeCode::Harvesting as u8,
            arms_enabled: [1, u8::from(config.arms >= 2)],
            field_hold: u8::from(cycle.holds_approaches()),
            ..OperatorModeState::default()
        };
        episode.publish_mode(mode);
        episode.tick(now_ns)?;

        // 5. The robot moves through the world.
        platform.step(period_s);
        tractor.step(period_s);
        episode
            .robot()
            .borrow_mut()
            .world_mut()
            .set_robot_offset_m(offset(platform.position_m(), tractor.position_m()));

        // 6. Assignments and ended attempts.
        let attempts = &episode.recorder().attempts;
        if attempts.len() > seen_attempts {
            cycle.on_assigned(now_ns);
        }
        seen_attempts = attempts.len();
        for attempt in attempts {
            if attempt.ended_s.is_some() {
                let key = (attempt.arm, attempt.dispatched_s.to_bits());
                if ended.insert(key) {
                    let cause = attempt.cause.map(|c| format!("{c:?}")).unwrap_or_default();
                    cycle.on_attempt_ended(now_ns, attempt.harvested, &cause);
                    last_end_ns = now_ns;
                }
            }
        }
    }
    let row_s = row_report
        .as_ref()
        .map_or(Episode::t_s(episode.now_ns()), |r| {
            r.duration_ns as f64 * 1e-9
        });
    let frames = detections.frames();
    let world = episode.robot().borrow().world().clone();
    let outcome = episode.finish(truncated);
    Ok(RowOutcome {
        name: config.name.clone(),
        seed: config.seed,
        arms: config.arms,
        apples_on_row,
        reachable,
        stops: stops_out,
        row_report,
        row_s,
        frames,
        episode: outcome,
        world,
    })
}
