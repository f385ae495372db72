//! Summaries of harvesting episodes, the report of `harvest eval harvest`, and the entry point
//! [`run_eval_harvest`].
//!
//! Definitions ([dual-arm sec. 4.2, Table 2]):
//! - an *attempt* is one target taken by an arm (or dispatched and never taken), until the arm
//!   is idle again;
//! - *attempted apples* are the true apples at least one attempt aimed at; *harvested* ones
//!   ended on the dropping module; *first-attempt successes* were harvested by their first
//!   attempt;
//! - *duration* runs from the start of the episode to the end of its last attempt; *seconds per
//!   apple* and *per attempt* divide it by the harvested apples and by the attempts (the field's
//!   "cycle time per attempt");
//! - the *release interval* is the mean time between consecutive apples landing on the dropping
//!   module within an episode, `(t_last - t_first) / (n - 1)`: the dashed-line spacing of
//!   Fig. 12 without the start-up of the first cycle;
//! - the *steady-state interval* is the same, counting only the releases up to the end of the
//!   last attempt of the arm that finished first (both arms busy). It is Fig. 12's measure:
//!   the paper's 2.25 s is "half the dashed-line spacing" of the interleaved timeline, with
//!   apples at uniform distances, no start-up and no end;
//! - the *whole-run* figure is `seconds_per_apple` above: everything from the start of the
//!   episode (the first detection set arrives 0.1 s in) to the end of the last attempt, so it
//!   includes the first cycle with no release before it and the tail where one arm has no
//!   apple left. [`TimeBudget`] splits it up; its `balanced_seconds_per_apple` is the floor
//!   the whole-run figure can reach with the same attempt durations.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use harvest_arm::node::ArmNodeConfig;
use harvest_log::CycleRates;
use harvest_vacuum::pressure::PressureConfig;
use serde::Serialize;

use super::args::{EvalHarvestArgs, PolicyArg, TimingArg};
use super::calibration::pressure_for;
use super::detections::DetectionModel;
use super::error::HarvestEvalError;
use super::records::FailureCause;
use super::records::{AppleRecord, AttemptRecord, EpisodeLogEntry};
use super::runner::{EmergencyStopReaction, EpisodeConfig, EpisodeOutcome, run_episode};
use super::timing::apply_timing;
use crate::laser::refinement::Summary;

/// Mean phase durations over the attempts that reached each phase, s.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct PhaseMeans {
    /// Approach.
    pub approach_s: Option<f64>,
    /// Attach and detach (waiting for the valve included).
    pub attach_s: Option<f64>,
    /// Retract.
    pub retract_s: Option<f64>,
    /// Release at the drop-off.
    pub release_s: Option<f64>,
}

/// Where the harvesting arms' time went, summed over the episodes and over the arms that
/// harvest: for every arm, `startup_s + attempts_s + between_attempts_s + tail_s` is the
/// episode's duration, so the four fields add up to `arms x duration_s`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TimeBudget {
    /// From the start of the episode to the arm's first dispatch (first detection set and its
    /// latency), s.
    pub startup_s: f64,
    /// Inside attempts, from dispatch to the arm idle again, s.
    pub attempts_s: f64,
    /// Between the end of one attempt and the next dispatch to the same arm, s.
    pub between_attempts_s: f64,
    /// From the arm's last attempt to the end of the episode (the other arm still working), s.
    pub tail_s: f64,
    /// Attempt time per harvesting arm over the harvested apples: the seconds per apple if the attempts were spread
    /// evenly over the arms with no start-up, gap or tail (the floor the whole-run figure
    /// can reach with these attempt durations), s.
    pub balanced_seconds_per_apple: Option<f64>,
}

impl TimeBudget {
    /// Adds the budget of one episode; returns its attempt time per harvesting arm, s.
    fn add_episode(&mut self, outcome: &EpisodeOutcome) -> f64 {
        let before_s = self.attempts_s;
        for arm in 1..=outcome.arms {
            let mut end_s = 0.0;
            let mut first = true;
            for a in outcome.recorder.attempts.iter().filter(|a| a.arm == arm) {
                let ended_s = a.ended_s.unwrap_or(outcome.duration_s);
                if first {
                    self.startup_s += a.dispatched_s;
                    first = false;
                } else {
                    self.between_attempts_s += (a.dispatched_s - end_s).max(0.0);
                }
                self.attempts_s += ended_s - a.dispatched_s;
                end_s = ended_s;
            }
            self.tail_s += (outcome.duration_s - end_s).max(0.0);
        }
        (self.attempts_s - before_s) / f64::from(outcome.arms.max(1))
    }
}

/// Counts and times of one or more episodes.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct HarvestSummary {
    /// Episodes summarized.
    pub episodes: u32,
    /// Apples in the worlds.
    pub apples_in_world: u32,
    /// Apples at least one attempt aimed at.
    pub apples_attempted: u32,
    /// Apples on the dropping module at the end.
    pub apples_harvested: u32,
    /// `apples_harvested / apples_attempted`.
    pub success_rate: Option<f64>,
    /// Apples harvested by their first attempt.
    pub first_attempt_successes: u32,
    /// Attempts.
    pub attempts: u32,
    /// Attempts that did not harvest, by cause.
    pub failure_causes: BTreeMap<String, u32>,
    /// `missed_apple` attempts (the cup never sealed on any apple): their target's distance to
    /// the apple it was near, mm, and how many were near none.
    pub missed_target_error_mm: Summary,
    pub missed_near_no_apple: u32,
    /// Sum of the episodes' durations, s.
    pub duration_s: f64,
    /// `duration_s / apples_harvested`, s.
    pub seconds_per_apple: Option<f64>,
    /// `duration_s / attempts`, s.
    pub seconds_per_attempt: Option<f64>,
    /// Mean interval between consecutive releases within an episode, s.
    pub release_interval_s: Option<f64>,
    /// The same, counting only the releases up to the end of the last attempt of the arm that
    /// finished first (both arms busy: Fig. 12's steady state), s.
    pub steady_release_interval_s: Option<f64>,
    /// Mean phase durations, s.
    pub mean_phase: PhaseMeans,
    /// Where the arms' time went.
    pub time_budget: TimeBudget,
    /// Episodes cut by the time limit.
    pub truncated_episodes: u32,
    /// Safety-monitor violations.
    pub safety_violations: u32,
    /// Trace events the safety monitor judged.
    pub trace_events: u64,
}

impl HarvestSummary {
    /// The summary of `outcomes`.
    pub fn of(outcomes: &[&EpisodeOutcome]) -> Self {
        let mut s = HarvestSummary::default();
        let mut release_span_s = 0.0;
        let mut release_gaps = 0u32;
        let mut steady_span_s = 0.0;
        let mut steady_gaps = 0u32;
        let mut phase_sum = [0.0; 4];
        let mut phase_n = [0u32; 4];
        let mut balanced_s = 0.0;
        let mut missed_errors_mm = Vec::new();
        for o in outcomes {
            s.episodes += 1;
            s.apples_in_world += o.apples_in_world;
            s.apples_attempted += o.apples.len() as u32;
            s.apples_harvested += o.apples.iter().filter(|a| a.harvested).count() as u32;
            s.first_attempt_successes +=
                o.apples.iter().filter(|a| a.first_attempt_success).count() as u32;
            s.attempts += o.recorder.attempts.len() as u32;
            for a in &o.recorder.attempts {
                if let Some(cause) = a.cause {
                    let key = serde_json::to_value(cause)
                        .ok()
                        .and_then(|v| v.as_str().map(str::to_owned))
                        .unwrap_or_else(|| format!("{cause:?}"));
                    *s.failure_causes.entry(key).or_insert(0) += 1;
                }
                if a.cause == Some(FailureCause::MissedApple) {
                    match a.target_error_m {
                        Some(error_m) => missed_errors_mm.push(error_m * 1e3),
                        None => s.missed_near_no_apple += 1,
                    }
                }
                for (k, d) in a.phase_durations_s().iter().enumerate() {
                    if let Some(d) = d {
                        phase_sum[k] += d;
                        phase_n[k] += 1;
                    }
                }
            }
            s.duration_s += o.duration_s;
            let r = &o.recorder.releases_s;
            if r.len() >= 2 {
                release_span_s += r[r.len() - 1] - r[0];
                release_gaps += r.len() as u32 - 1;
            }
            let window_end_s = [1u8, 2]
                .iter()
                .filter_map(|arm| {
                    o.recorder
                        .attempts
                        .iter()
                        .filter(|a| a.arm == *arm)
                        .filter_map(|a| a.ended_s)
                        .reduce(f64::max)
                })
                .reduce(f64::min);
            if let Some(end_s) = window_end_s {
                let steady: Vec<f64> = r.iter().copied().filter(|t| *t <= end_s).collect();
                if steady.len() >= 2 {
                    steady_span_s += steady[steady.len() - 1] - steady[0];
                    steady_gaps += steady.len() as u32 - 1;
                }
            }
            balanced_s += s.time_budget.add_episode(o);
            s.truncated_episodes += u32::from(o.truncated);
            s.safety_violations += o.violations.len() as u32;
            s.trace_events += o.trace_events;
        }
        let rates = CycleRates::new(
            s.apples_attempted,
            s.apples_harvested,
            s.attempts,
            s.duration_s,
        );
        s.missed_target_error_mm = Summary::of(missed_errors_mm);
        s.success_rate = rates.success_rate;
        s.seconds_per_apple = rates.seconds_per_apple;
        s.seconds_per_attempt = rates.seconds_per_attempt;
        s.release_interval_s = (release_gaps > 0).then(|| release_span_s / f64::from(release_gaps));
        s.steady_release_interval_s =
            (steady_gaps > 0).then(|| steady_span_s / f64::from(steady_gaps));
        s.time_budget.balanced_seconds_per_apple =
            (s.apples_harvested > 0).then(|| balanced_s / f64::from(s.apples_harvested));
        let mean = |k: usize| (phase_n[k] > 0).then(|| phase_sum[k] / f64::from(phase_n[k]));
        s.mean_phase = PhaseMeans {
            approach_s: mean(0),
            attach_s: mean(1),
            retract_s: mean(2),
            release_s: mean(3),
        };
        s
    }
}

/// Mean and worst of one emergency-stop delay over the trials, s.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct DelayStats {
    /// Trials where it happened before the episode ended.
    pub measured: u32,
    /// Mean, s.
    pub mean_s: Option<f64>,
    /// Worst, s.
    pub max_s: Option<f64>,
}

impl DelayStats {
    fn of(values: impl Iterator<Item = Option<f64>>) -> Self {
        let (mut n, mut sum, mut max) = (0u32, 0.0, None::<f64>);
        for v in values.flatten() {
            n += 1;
            sum += v;
            max = Some(max.map_or(v, |m| m.max(v)));
        }
        Self {
            measured: n,
            mean_s: (n > 0).then(|| sum / f64::from(n)),
            max_s: max,
        }
    }
}

/// The emergency-stop reaction measured in simulated time: `safety/emergency_stop` engaged at
/// staggered times of harvesting episodes (so every phase of the cycle is hit), then the delays
/// until the stack had commanded everything off, the board reported every gate closed at its
/// end stop, both arms published `Stopped` (drives braked) and both arms were still.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct EmergencyStopSummary {
    /// Trials run.
    pub trials: u32,
    /// Request to every valve commanded closed and both drives told to brake.
    pub commanded: DelayStats,
    /// Request to every gate reported closed.
    pub valves_closed: DelayStats,
    /// Request to both arms reporting `Stopped`.
    pub arms_holding: DelayStats,
    /// Request to both arms still (joints slower than 1 mm/s, 1 mrad/s).
    pub arms_stopped: DelayStats,
    /// Gate travel time of the simulated valves, s (the physical floor of `valves_closed`).
    pub valve_travel_s: f64,
    /// Safety violations during the trials.
    pub safety_violations: u32,
}

/// Runs `trials` episodes of `base` with the stop engaged at `0.5 s + k x 0.373 s` (spread over
/// the cycle) and summarizes the reactions.
pub fn measure_emergency_stop(
    base: &EpisodeConfig,
    trials: u32,
) -> Result<EmergencyStopSummary, HarvestEvalError> {
    let mut reactions = Vec::with_capacity(trials as usize);
    let mut violations = 0u32;
    for k in 0..trials {
        let mut config = base.clone();
        config.seed = base.seed + u64::from(k);
        config.emergency_stop_at_s = Some(0.5 + 0.373 * f64::from(k));
        config.keep_events = false;
        // The stop is expected here: the nodes' warnings about it are not shown.
        let outcome = tracing::subscriber::with_default(
            tracing::subscriber::NoSubscriber::default(),
            || run_episode(&config),
        )?;
        violations += outcome.violations.len() as u32;
        if let Some(m) = outcome.emergency_stop {
            reactions.push(m);
        }
    }
    Ok(EmergencyStopSummary {
        trials,
        commanded: DelayStats::of(reactions.iter().map(|m| m.commanded_s)),
        valves_closed: DelayStats::of(reactions.iter().map(|m| m.valves_closed_s)),
        arms_holding: DelayStats::of(reactions.iter().map(|m| m.arms_holding_s)),
        arms_stopped: DelayStats::of(reactions.iter().map(|m| m.arms_stopped_s)),
        valve_travel_s: base.scenario.vacuum.valve_travel_time_s,
        safety_violations: violations,
    })
}

/// One episode in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeReport {
    /// World seed.
    pub seed: u64,
    /// Its summary.
    pub summary: HarvestSummary,
    /// Per attempted apple.
    pub apples: Vec<AppleRecord>,
    /// Per attempt.
    pub attempts: Vec<AttemptRecord>,
    /// The event log.
    pub events: Vec<EpisodeLogEntry>,
    /// Safety violations, described.
    pub violations: Vec<String>,
    /// Emergency-stop measurement, if requested.
    pub emergency_stop: Option<EmergencyStopReaction>,
}

impl EpisodeReport {
    /// The report of one outcome.
    pub fn of(outcome: &EpisodeOutcome) -> Self {
        Self {
            seed: outcome.seed,
            summary: HarvestSummary::of(&[outcome]),
            apples: outcome.apples.clone(),
            attempts: outcome.recorder.attempts.clone(),
            events: outcome.recorder.events.clone(),
            violations: outcome
                .violations
                .iter()
                .map(|v| format!("{v:?}"))
                .collect(),
            emergency_stop: outcome.emergency_stop.clone(),
        }
    }
}

/// The report of `harvest eval harvest`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HarvestReport {
    /// Scenario name.
    pub scenario: String,
    /// Policy.
    pub policy: PolicyArg,
    /// Harvesting arms.
    pub arms: u8,
    /// Hardware timing profile.
    pub timing: TimingArg,
    /// Detection noise scale.
    pub detection_noise: f64,
    /// First seed.
    pub seed: u64,
    /// Over all episodes.
    pub summary: HarvestSummary,
    /// Each episode.
    pub episodes: Vec<EpisodeReport>,
    /// The emergency-stop reaction (`--estop-trials` > 0).
    pub emergency_stop: Option<EmergencyStopSummary>,
}

fn opt(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "-".to_owned(), |v| format!("{v:.digits$}"))
}

impl HarvestReport {
    /// A human-readable summary (what the CLI prints).
    pub fn render_text(&self) -> String {
        let s = &self.summary;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "harvest eval: scenario {}, policy {:?}, {} arm(s), timing {:?}, {} episode(s) from \
             seed {}",
            self.scenario, self.policy, self.arms, self.timing, s.episodes, self.seed
        );
        let _ = writeln!(
            out,
            "  apples: {} in world, {} attempted, {} harvested (success {}), {} on first attempt",
            s.apples_in_world,
            s.apples_attempted,
            s.apples_harvested,
            opt(s.success_rate.map(|r| r * 100.0), 1) + " %",
            s.first_attempt_successes
        );
        let _ = writeln!(
            out,
            "  attempts: {}; time {:.1} s: whole run {} s/apple, {} s/attempt; release \
             interval {} s, steady state (both arms busy) {} s",
            s.attempts,
            s.duration_s,
            opt(s.seconds_per_apple, 2),
            opt(s.seconds_per_attempt, 2),
            opt(s.release_interval_s, 2),
            opt(s.steady_release_interval_s, 2)
        );
        let b = &s.time_budget;
        let _ = writeln!(
            out,
            "  arm time: start-up {:.2} s, in attempts {:.2} s, between attempts {:.2} s, tail \
             (no apple left while the other arm works) {:.2} s; attempts spread evenly: {} \
             s/apple",
            b.startup_s,
            b.attempts_s,
            b.between_attempts_s,
            b.tail_s,
            opt(b.balanced_seconds_per_apple, 2)
        );
        let p = &s.mean_phase;
        let _ = writeln!(
            out,
            "  mean phases: approach {} s, attach {} s, retract {} s, release {} s",
            opt(p.approach_s, 2),
            opt(p.attach_s, 2),
            opt(p.retract_s, 2),
            opt(p.release_s, 2)
        );
        if !s.failure_causes.is_empty() {
            let causes: Vec<String> = s
                .failure_causes
                .iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect();
            let _ = writeln!(out, "  failed attempts: {}", causes.join(", "));
        }
        let m = &s.missed_target_error_mm;
        if m.count > 0 || s.missed_near_no_apple > 0 {
            let _ = writeln!(
                out,
                "  missed_apple targets from their apple: median {:.1} / p95 {:.1} / max {:.1} mm over {}; near no apple {}",
                m.median, m.p95, m.max, m.count, s.missed_near_no_apple
            );
        }
        let _ = writeln!(
            out,
            "  safety: {} violations in {} trace events; {} truncated episode(s)",
            s.safety_violations, s.trace_events, s.truncated_episodes
        );
        if let Some(e) = &self.emergency_stop {
            let d =
                |d: &DelayStats| format!("mean {} / worst {} s", opt(d.mean_s, 3), opt(d.max_s, 3));
            let _ = writeln!(
                out,
                "  emergency stop ({} trials, simulated time): commanded {}; all valves closed \
                 {} (gate travel {:.2} s); both arms holding {}; both arms still {}; {} \
                 violations",
                e.trials,
                d(&e.commanded),
                d(&e.valves_closed),
                e.valve_travel_s,
                d(&e.arms_holding),
                d(&e.arms_stopped),
                e.safety_violations
            );
        }
        out
    }
}

/// Runs `harvest eval harvest`: `args.episodes` episodes of the scenario with seeds `seed`,
/// `seed + 1`, ... and the chosen policy, arms and timing; writes the JSON report if asked.
pub fn run_eval_harvest(args: &EvalHarvestArgs) -> Result<HarvestReport, HarvestEvalError> {
    if args.episodes == 0 {
        return Err(HarvestEvalError::InvalidArgument {
            arg: "--episodes",
            value: "0".to_owned(),
            reason: "at least one episode",
        });
    }
    if !(args.detection_noise.is_finite() && args.detection_noise >= 0.0) {
        return Err(HarvestEvalError::InvalidArgument {
            arg: "--detection-noise",
            value: args.detection_noise.to_string(),
            reason: "must be finite and >= 0",
        });
    }
    let mut scenario = harvest_sim::process::load_scenario(&args.scenario)?;
    let mut arm_node = ArmNodeConfig::default();
    let mut pressure = PressureConfig::default();
    apply_timing(&mut scenario, &mut arm_node, &mut pressure, args.timing);
    let pressure = pressure_for(&scenario.vacuum, pressure)?;
    let mut outcomes = Vec::with_capacity(args.episodes as usize);
    for k in 0..args.episodes {
        let mut config = EpisodeConfig::new(
            scenario.clone(),
            args.policy.kind(),
            args.arms,
            args.seed + u64::from(k),
        );
        config.max_episode_s = args.max_episode_s;
        config.arm_node = arm_node;
        config.pressure = pressure;
        config.detection = DetectionModel {
            noise_scale: args.detection_noise,
            ..DetectionModel::default()
        };
        config.keep_events = args.json.is_some();
        let outcome = run_episode(&config)?;
        tracing::info!(
            seed = outcome.seed,
            attempts = outcome.recorder.attempts.len(),
            harvested = outcome.apples.iter().filter(|a| a.harvested).count(),
            duration_s = outcome.duration_s,
            "harvest episode done"
        );
        outcomes.push(outcome);
    }
    let emergency_stop = if args.estop_trials > 0 {
        let mut base =
            EpisodeConfig::new(scenario.clone(), args.policy.kind(), args.arms, args.seed);
        base.arm_node = arm_node;
        base.pressure = pressure;
        base.detection = DetectionModel {
            noise_scale: args.detection_noise,
            ..DetectionModel::default()
        };
        Some(measure_emergency_stop(&base, args.estop_trials)?)
    } else {
        None
    };
    let refs: Vec<&EpisodeOutcome> = outcomes.iter().collect();
    let report = HarvestReport {
        scenario: scenario.name.clone(),
        policy: args.policy,
        arms: args.arms,
        timing: args.timing,
        detection_noise: args.detection_noise,
        seed: args.seed,
        summary: HarvestSummary::of(&refs),
        episodes: outcomes.iter().map(EpisodeReport::of).collect(),
        emergency_stop,
    };
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report).map_err(|e| HarvestEvalError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|e| HarvestEvalError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
    }
    Ok(report)
}
