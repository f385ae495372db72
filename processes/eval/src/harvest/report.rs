//! Summaries of harvesting episodes, the report of `harvest eval harvest`, and the entry point
//! [`run_eval_harvest`].
//!
//! Definitions (paper 003, section 4.2 and Table 2):
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
//!   Fig. 12 without the start-up of the first cycle.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use harvest_arm::node::ArmNodeConfig;
use harvest_vacuum::pressure::PressureConfig;
use serde::Serialize;

use super::args::{EvalHarvestArgs, PolicyArg, TimingArg};
use super::calibration::calibrated_pressure;
use super::detections::DetectionModel;
use super::error::HarvestEvalError;
use super::records::{AppleRecord, AttemptRecord, HarvestEvent};
use super::runner::{EmergencyStopReaction, EpisodeConfig, EpisodeOutcome, run_episode};
use super::timing::apply_timing;

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
            s.truncated_episodes += u32::from(o.truncated);
            s.safety_violations += o.violations.len() as u32;
            s.trace_events += o.trace_events;
        }
        s.success_rate = (s.apples_attempted > 0)
            .then(|| f64::from(s.apples_harvested) / f64::from(s.apples_attempted));
        s.seconds_per_apple =
            (s.apples_harvested > 0).then(|| s.duration_s / f64::from(s.apples_harvested));
        s.seconds_per_attempt = (s.attempts > 0).then(|| s.duration_s / f64::from(s.attempts));
        s.release_interval_s = (release_gaps > 0).then(|| release_span_s / f64::from(release_gaps));
        s.steady_release_interval_s =
            (steady_gaps > 0).then(|| steady_span_s / f64::from(steady_gaps));
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
    pub events: Vec<HarvestEvent>,
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
            "  attempts: {}; time {:.1} s: {} s/apple, {} s/attempt; release interval {} s \
             (both arms busy: {} s)",
            s.attempts,
            s.duration_s,
            opt(s.seconds_per_apple, 2),
            opt(s.seconds_per_attempt, 2),
            opt(s.release_interval_s, 2),
            opt(s.steady_release_interval_s, 2)
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
        let _ = writeln!(
            out,
            "  safety: {} violations in {} trace events; {} truncated episode(s)",
            s.safety_violations, s.trace_events, s.truncated_episodes
        );
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
    let pressure = calibrated_pressure(&scenario.vacuum, pressure);
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
