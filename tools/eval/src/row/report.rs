//! The report of `harvest eval row` and its entry point [`run_eval_row`].
//!
//! Definitions:
//! - *attempts* are targets taken by an arm (or dispatched and never taken); *attempted apples*
//!   the true apples an attempt aimed at; *success rate per attempt* is harvested / attempts,
//!   *per apple* harvested / attempted apples (Table 2's);
//! - *cycle time per attempt* is the time the stops spent harvesting (from the first fresh
//!   set after positioning to the stop done) over the attempts, the field's "average cycle time
//!   per attempt" ([dual-arm sec. 4.2]: dual 5.97 s, single 8.29 s); the same with the
//!   whole row (travel, parking, positioning, settling) is printed beside it;
//! - *positioning ratio*: apples in reach (ground truth, at the start of each stop's harvest)
//!   with the chosen platform offsets over those in reach with the platform at its fixed
//!   position (stages at 0), same world, same moment, summed over the stops.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use harvest_arm::node::ArmNodeConfig;
use harvest_sim::row::RowScenario;
use harvest_vacuum::pressure::PressureConfig;
use serde::Serialize;

use super::args::{DetectionsArg, EvalRowArgs};
use super::error::RowEvalError;
use super::failures::{
    FailedAttempt, FailureOrigin, failed_attempts, left_after_slip, origin_counts, render_line,
};
use super::perception_loop::FramePolicy;
use super::runner::{RowOutcome, RowRunConfig, StopFigures, run_row};
use super::truth::{Table3Cause, attempt_causes, missed_causes};
use crate::harvest::calibration::pressure_for;
use crate::harvest::timing::apply_timing;

/// The rows of `sim/rows/`, by name.
const ROW_PRESETS: [(&str, &str); 2] = [
    (
        "two_stops",
        include_str!("../../../../sim/rows/two_stops.toml"),
    ),
    (
        "three_sections",
        include_str!("../../../../sim/rows/three_sections.toml"),
    ),
];

/// Per orchard, [dual-arm Table 2]: (orchard, attempted, success, 1st attempt, >= 2 attempts).
pub const PAPER_TABLE_2: [(u32, u32, u32, u32, u32); 2] =
    [(1, 322, 260, 222, 38), (2, 285, 227, 201, 26)];
/// Field cycle time per attempt of [dual-arm sec. 4.2], dual and single arm, s.
pub const PAPER_CYCLE_PER_ATTEMPT_S: (f64, f64) = (5.97, 8.29);

/// Loads a row by preset name or file path.
pub fn load_row(name: &str) -> Result<RowScenario, RowEvalError> {
    let error = |source| RowEvalError::Row {
        row: name.to_owned(),
        source: Box::new(source),
    };
    match ROW_PRESETS.iter().find(|(preset, _)| *preset == name) {
        Some((preset, text)) => {
            RowScenario::from_toml_str(&format!("sim/rows/{preset}.toml"), text).map_err(error)
        }
        None => RowScenario::from_file(std::path::Path::new(name)).map_err(error),
    }
}

/// The figures a row run and a sum of runs share; a sum of runs adds them (`RowCounts::add`).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct RowCounts {
    pub apples_on_row: usize,
    /// In reach (ground truth) at some stop with the chosen offsets.
    pub reachable: usize,
    /// On the row but never in reach: counted, not dropped.
    pub out_of_reach: usize,
    pub attempts: u32,
    pub apples_attempted: u32,
    pub harvested: u32,
    pub first_attempt_successes: u32,
    /// In reach, never attempted, still on the tree.
    pub missed: u32,
    /// Table 3 causes of the failed attempts (an attempt may count under several perception
    /// causes, as in the paper).
    pub failures: BTreeMap<Table3Cause, u32>,
    /// Failed attempts caused by perception (each once).
    pub perception_failures: u32,
    /// Missed apples by their perception flags.
    pub missed_causes: BTreeMap<Table3Cause, u32>,
    pub harvest_s: f64,
    pub row_s: f64,
    pub safety_violations: u32,
    /// Failed attempts by what decided them ([`FailureOrigin`]).
    pub origins: BTreeMap<FailureOrigin, u32>,
    /// Picking-point error (target to true centre) of the attempts that matched an apple:
    /// sum and count, mm.
    pub target_error_sum_mm: f64,
    pub target_error_count: u32,
    /// Apples left on the tree after their last attempt slipped (skipped, not dropped).
    pub left_after_slip: u32,
}

impl RowCounts {
    /// Adds `other`'s figures to these.
    fn add(&mut self, other: &RowCounts) {
        fn add_map<K: Ord + Copy>(into: &mut BTreeMap<K, u32>, from: &BTreeMap<K, u32>) {
            for (key, n) in from {
                *into.entry(*key).or_insert(0) += n;
            }
        }
        self.apples_on_row += other.apples_on_row;
        self.reachable += other.reachable;
        self.out_of_reach += other.out_of_reach;
        self.attempts += other.attempts;
        self.apples_attempted += other.apples_attempted;
        self.harvested += other.harvested;
        self.first_attempt_successes += other.first_attempt_successes;
        self.missed += other.missed;
        add_map(&mut self.failures, &other.failures);
        self.perception_failures += other.perception_failures;
        add_map(&mut self.missed_causes, &other.missed_causes);
        self.harvest_s += other.harvest_s;
        self.row_s += other.row_s;
        self.safety_violations += other.safety_violations;
        add_map(&mut self.origins, &other.origins);
        self.target_error_sum_mm += other.target_error_sum_mm;
        self.target_error_count += other.target_error_count;
        self.left_after_slip += other.left_after_slip;
    }
}

/// One row run, summarized.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RowRunReport {
    pub row: String,
    pub seed: u64,
    pub arms: u8,
    #[serde(flatten)]
    pub counts: RowCounts,
    /// Detected at the stops (stop cycle, before positioning).
    pub detected: usize,
    /// Failed attempts by the harvest evaluation's cause.
    pub failure_detail: BTreeMap<String, u32>,
    pub frames: u64,
    pub truncated: bool,
    pub stops: Vec<StopFigures>,
    /// Every failed attempt with the ground truth behind it.
    pub failed: Vec<FailedAttempt>,
}

impl RowRunReport {
    /// The summary of `outcome`.
    pub fn of(outcome: &RowOutcome) -> Self {
        let attempts = &outcome.episode.recorder.attempts;
        let mut failures = BTreeMap::new();
        let mut failure_detail = BTreeMap::new();
        let mut perception_failures = 0;
        for attempt in attempts {
            let causes = attempt_causes(&outcome.world, attempt);
            if causes.is_empty() {
                continue;
            }
            if causes.iter().any(|c| {
                matches!(
                    c,
                    Table3Cause::Exposure
                        | Table3Cause::Occlusion
                        | Table3Cause::Cluster
                        | Table3Cause::Localization
                        | Table3Cause::FalseDetection
                )
            }) {
                perception_failures += 1;
            }
            for cause in causes {
                *failures.entry(cause).or_insert(0) += 1;
            }
            let detail = attempt
                .cause
                .map_or_else(|| "unclassified".to_owned(), |c| format!("{c:?}"));
            *failure_detail.entry(detail).or_insert(0) += 1;
        }
        let apples = &outcome.episode.apples;
        let attempted: std::collections::BTreeSet<u32> = apples.iter().map(|a| a.apple).collect();
        let missed: Vec<u32> = outcome
            .reachable
            .iter()
            .copied()
            .filter(|id| {
                !attempted.contains(id)
                    && outcome
                        .world
                        .apples()
                        .get(*id as usize)
                        .is_some_and(|a| a.state == harvest_sim::AppleState::OnTree)
            })
            .collect();
        let failed = failed_attempts(&outcome.world, attempts);
        let errors: Vec<f64> = attempts.iter().filter_map(|a| a.target_error_m).collect();
        Self {
            counts: RowCounts {
                apples_on_row: outcome.apples_on_row,
                reachable: outcome.reachable.len(),
                out_of_reach: outcome.apples_on_row - outcome.reachable.len(),
                attempts: attempts.len() as u32,
                apples_attempted: apples.len() as u32,
                harvested: outcome.harvested() as u32,
                first_attempt_successes: apples.iter().filter(|a| a.first_attempt_success).count()
                    as u32,
                missed: missed.len() as u32,
                failures,
                perception_failures,
                missed_causes: missed_causes(&outcome.world, &missed),
                harvest_s: outcome.stops.iter().map(|s| s.harvest_s).sum(),
                row_s: outcome.row_s,
                safety_violations: outcome.episode.violations.len() as u32,
                origins: origin_counts(&failed),
                target_error_sum_mm: errors.iter().sum::<f64>() * 1e3,
                target_error_count: errors.len() as u32,
                left_after_slip: left_after_slip(&outcome.world, attempts),
            },
            failed,
            row: outcome.name.clone(),
            seed: outcome.seed,
            arms: outcome.arms,
            detected: outcome.stops.iter().map(|s| s.cycle.detected).sum(),
            failure_detail,
            frames: outcome.frames,
            truncated: outcome.row_report.is_none(),
            stops: outcome.stops.clone(),
        }
    }
}

/// Rows and seeds of one arm count, summed.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct ArmSummary {
    pub arms: u8,
    pub runs: u32,
    #[serde(flatten)]
    pub counts: RowCounts,
    pub reach_chosen: usize,
    pub reach_fixed: usize,
    pub truncated: u32,
}

impl ArmSummary {
    fn add(&mut self, run: &RowRunReport) {
        self.arms = run.arms;
        self.runs += 1;
        self.counts.add(&run.counts);
        self.reach_chosen += run
            .stops
            .iter()
            .map(|s| s.truth_reachable_chosen)
            .sum::<usize>();
        self.reach_fixed += run
            .stops
            .iter()
            .map(|s| s.truth_reachable_fixed)
            .sum::<usize>();
        self.truncated += u32::from(run.truncated);
    }

    /// Failed attempts the simulator's stochastic models decided whatever the stack did.
    pub fn simulator_decided(&self) -> u32 {
        self.counts
            .origins
            .iter()
            .filter(|(o, _)| o.simulator_decided())
            .map(|(_, n)| n)
            .sum()
    }

    /// Harvested / attempts.
    pub fn success_per_attempt(&self) -> Option<f64> {
        ratio(self.counts.harvested as f64, self.counts.attempts as f64)
    }

    /// Harvested / attempted apples (Table 2's).
    pub fn success_per_apple(&self) -> Option<f64> {
        ratio(
            self.counts.harvested as f64,
            self.counts.apples_attempted as f64,
        )
    }

    /// Harvesting time over attempts, s.
    pub fn seconds_per_attempt(&self) -> Option<f64> {
        ratio(self.counts.harvest_s, self.counts.attempts as f64)
    }

    /// Whole-row time over attempts, s.
    pub fn row_seconds_per_attempt(&self) -> Option<f64> {
        ratio(self.counts.row_s, self.counts.attempts as f64)
    }

    /// Whole-row time over harvested apples, s.
    pub fn row_seconds_per_apple(&self) -> Option<f64> {
        ratio(self.counts.row_s, self.counts.harvested as f64)
    }

    /// Truth reach with the chosen offsets over the fixed position.
    pub fn positioning_ratio(&self) -> Option<f64> {
        ratio(self.reach_chosen as f64, self.reach_fixed as f64)
    }
}

/// Appends `counts[key]` (0 when absent) for each of `keys`, one 12-wide cell each.
fn count_cells<K: Ord>(
    line: &mut String,
    keys: impl IntoIterator<Item = K>,
    counts: &BTreeMap<K, u32>,
) {
    for key in keys {
        let _ = write!(line, " {:>12}", counts.get(&key).copied().unwrap_or(0));
    }
}

fn ratio(a: f64, b: f64) -> Option<f64> {
    (b > 0.0).then(|| a / b)
}

/// The report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RowEvalReport {
    pub rows: Vec<String>,
    pub seed: u64,
    pub seeds: u32,
    pub detections: DetectionsArg,
    pub frame_interval_s: f64,
    /// Print every failed attempt (`--failures`).
    pub list_failures: bool,
    pub runs: Vec<RowRunReport>,
    pub by_arms: Vec<ArmSummary>,
}

impl RowEvalReport {
    /// Dual-arm time per attempt relative to single arm: `1 - dual / single`.
    pub fn dual_saving(&self) -> Option<f64> {
        let of = |arms| {
            self.by_arms
                .iter()
                .find(|s| s.arms == arms)
                .and_then(ArmSummary::seconds_per_attempt)
        };
        Some(1.0 - of(2)? / of(1)?)
    }

    /// The tables as text.
    pub fn render_text(&self) -> String {
        let mut out = String::new();
        let pct =
            |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{:.1} %", v * 100.0));
        let s = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.2} s"));
        let _ = writeln!(
            out,
            "harvest eval row: rows {}, seeds {}..{}, detections {:?}, frame at least every {} s while harvesting",
            self.rows.join(", "),
            self.seed,
            self.seed + u64::from(self.seeds.max(1)) - 1,
            self.detections,
            self.frame_interval_s
        );
        let _ = writeln!(
            out,
            "\nper row run (truth: on row / in reach / out of reach)"
        );
        for run in &self.runs {
            let _ = writeln!(
                out,
                "  {} seed {} arms {}: apples {}/{}/{}, detected {}, attempts {}, harvested {} \
                 (missed in reach {}), harvest {:.1} s, row {:.1} s, frames {}{}{}",
                run.row,
                run.seed,
                run.arms,
                run.counts.apples_on_row,
                run.counts.reachable,
                run.counts.out_of_reach,
                run.detected,
                run.counts.attempts,
                run.counts.harvested,
                run.counts.missed,
                run.counts.harvest_s,
                run.counts.row_s,
                run.frames,
                if run.truncated { ", TRUNCATED" } else { "" },
                if run.counts.safety_violations > 0 {
                    format!(", {} SAFETY VIOLATIONS", run.counts.safety_violations)
                } else {
                    String::new()
                }
            );
            for stop in &run.stops {
                let _ = writeln!(
                    out,
                    "    stop {} @{:.2} m: platform ({:.2}, {:.2}) m, detected {}, reach det {}->{} \
                     (out {}), truth fixed {} -> chosen {}, att {}, ok {}, {:.1} s",
                    stop.cycle.stop,
                    stop.cycle.trailer_m,
                    stop.cycle.offset_m[0],
                    stop.cycle.offset_m[1],
                    stop.cycle.detected,
                    stop.cycle.reachable_before,
                    stop.cycle.reachable_after,
                    stop.cycle.out_of_reach,
                    stop.truth_reachable_fixed,
                    stop.truth_reachable_chosen,
                    stop.attempts,
                    stop.harvested,
                    stop.stop_s
                );
            }
            if self.list_failures {
                for failed in &run.failed {
                    let _ = writeln!(out, "      failed: {}", render_line(failed));
                }
            }
        }
        let _ = writeln!(
            out,
            "\nTable 2 (structure of [dual-arm Table 2]), summed over rows and seeds"
        );
        let _ = writeln!(
            out,
            "  {:<14} {:>9} {:>14} {:>6} {:>6} {:>8} {:>10} {:>10} {:>10} {:>10}",
            "",
            "attempted",
            "success",
            "1st",
            ">=2",
            "attempts",
            "ok/att",
            "s/attempt",
            "row s/att",
            "row s/apple"
        );
        for (orchard, attempted, success, first, more) in PAPER_TABLE_2 {
            let _ = writeln!(
                out,
                "  {:<14} {:>9} {:>14} {:>6} {:>6} {:>8} {:>10} {:>10} {:>10} {:>10}",
                format!("paper orch. {orchard}"),
                attempted,
                format!(
                    "{success} ({:.1} %)",
                    f64::from(success) * 100.0 / f64::from(attempted)
                ),
                first,
                more,
                "-",
                "-",
                "-",
                "-",
                "-"
            );
        }
        for (arms, paper_s) in [
            (1u8, PAPER_CYCLE_PER_ATTEMPT_S.1),
            (2, PAPER_CYCLE_PER_ATTEMPT_S.0),
        ] {
            let _ = writeln!(
                out,
                "  {:<14} {:>9} {:>14} {:>6} {:>6} {:>8} {:>10} {:>10} {:>10} {:>10}",
                format!("paper {arms} arm"),
                "-",
                "-",
                "-",
                "-",
                "-",
                "-",
                format!("{paper_s:.2} s"),
                "-",
                "-"
            );
        }
        for sum in &self.by_arms {
            let _ = writeln!(
                out,
                "  {:<14} {:>9} {:>14} {:>6} {:>6} {:>8} {:>10} {:>10} {:>10} {:>10}",
                format!("sim {} arm", sum.arms),
                sum.counts.apples_attempted,
                format!(
                    "{} ({})",
                    sum.counts.harvested,
                    pct(sum.success_per_apple())
                ),
                sum.counts.first_attempt_successes,
                sum.counts
                    .harvested
                    .saturating_sub(sum.counts.first_attempt_successes),
                sum.counts.attempts,
                pct(sum.success_per_attempt()),
                s(sum.seconds_per_attempt()),
                s(sum.row_seconds_per_attempt()),
                s(sum.row_seconds_per_apple())
            );
        }
        let paper_saving = 1.0 - PAPER_CYCLE_PER_ATTEMPT_S.0 / PAPER_CYCLE_PER_ATTEMPT_S.1;
        let _ = writeln!(
            out,
            "  dual vs single arm, time per attempt: {} less (paper {:.1} % less; target >= 28 %)",
            pct(self.dual_saving()),
            paper_saving * 100.0
        );
        let _ = writeln!(
            out,
            "\nTable 3 (categories of [dual-arm Table 3]) over the failed attempts; perception \
             causes from the target apple's flags (several may apply, as in the paper)"
        );
        let mut header = format!("  {:<14}", "");
        for cause in Table3Cause::ALL {
            let _ = write!(header, " {:>12}", cause.label());
        }
        let _ = writeln!(out, "{header} {:>12}", "perception");
        let mut paper = format!("  {:<14}", "paper (videos)");
        for cause in Table3Cause::ALL {
            let _ = write!(
                paper,
                " {:>12}",
                cause
                    .paper_count()
                    .map_or_else(|| "-".to_owned(), |n| n.to_string())
            );
        }
        let _ = writeln!(out, "{paper} {:>12}", "-");
        for sum in &self.by_arms {
            let mut line = format!("  {:<14}", format!("sim {} arm", sum.arms));
            count_cells(&mut line, Table3Cause::ALL, &sum.counts.failures);
            let _ = writeln!(out, "{line} {:>12}", sum.counts.perception_failures);
            let mut missed = format!("  {:<14}", format!("  missed {}", sum.counts.missed));
            count_cells(&mut missed, Table3Cause::ALL, &sum.counts.missed_causes);
            let _ = writeln!(out, "{missed}");
        }
        let _ = writeln!(
            out,
            "  (missed: in reach, never attempted, left on the tree; by the apple's flags)"
        );
        let _ = writeln!(
            out,
            "\nfailed attempts by what decided them (ground truth; `--failures` lists them): \
             simulator draws (leaf, unripe stem beyond the cup at full vacuum with full twist \
             relief, branch) and stack decisions"
        );
        let mut header = format!("  {:<14}", "");
        for origin in FailureOrigin::ALL {
            let _ = write!(header, " {:>12}", origin.label());
        }
        let _ = writeln!(
            out,
            "{header} {:>8} {:>8} {:>14} {:>12} {:>10}",
            "failed", "sim", "ok/att if sim", "pick err", "left slip"
        );
        for sum in &self.by_arms {
            let mut line = format!("  {:<14}", format!("sim {} arm", sum.arms));
            count_cells(&mut line, FailureOrigin::ALL, &sum.counts.origins);
            let failed: u32 = sum.counts.origins.values().sum();
            let sim = sum.simulator_decided();
            let _ = writeln!(
                out,
                "{line} {:>8} {:>8} {:>14} {:>12} {:>10}",
                failed,
                sim,
                pct(ratio(
                    f64::from(sum.counts.attempts - sim),
                    f64::from(sum.counts.attempts)
                )),
                ratio(
                    sum.counts.target_error_sum_mm,
                    f64::from(sum.counts.target_error_count)
                )
                .map_or_else(|| "-".to_owned(), |e| format!("{e:.1} mm")),
                sum.counts.left_after_slip
            );
        }
        let _ = writeln!(
            out,
            "  (ok/att if sim: success per attempt had only the simulator's draws failed; pick err: \
             mean target-to-true-centre distance of the attempts that matched an apple; left slip: \
             apples left on the tree after their last attempt slipped)"
        );
        let _ = writeln!(
            out,
            "\nplatform positioning (ground truth, apples in reach summed over stops)"
        );
        for sum in &self.by_arms {
            let _ = writeln!(
                out,
                "  sim {} arm: fixed position {}, chosen offsets {}, ratio {}; row: {} apples, {} in \
                 reach, {} out of reach{}{}",
                sum.arms,
                sum.reach_fixed,
                sum.reach_chosen,
                sum.positioning_ratio()
                    .map_or_else(|| "-".to_owned(), |r| format!("{r:.2}")),
                sum.counts.apples_on_row,
                sum.counts.reachable,
                sum.counts.out_of_reach,
                if sum.truncated > 0 {
                    format!(", {} runs TRUNCATED", sum.truncated)
                } else {
                    String::new()
                },
                if sum.counts.safety_violations > 0 {
                    format!(", {} SAFETY VIOLATIONS", sum.counts.safety_violations)
                } else {
                    String::new()
                }
            );
        }
        out
    }
}

/// Checks the arguments.
fn validate(args: &EvalRowArgs) -> Result<(), RowEvalError> {
    let invalid = |arg, value: String, reason| RowEvalError::InvalidArgument { arg, value, reason };
    if args.rows.is_empty() {
        return Err(invalid("--rows", String::new(), "name at least one row"));
    }
    if args.seeds == 0 {
        return Err(invalid("--seeds", "0".to_owned(), "at least one seed"));
    }
    if args.arms.is_empty() {
        return Err(invalid("--arms", String::new(), "name 1, 2 or both"));
    }
    for (arg, value) in [
        ("--frame-interval-s", args.frame_interval_s),
        ("--perception-latency-s", args.perception_latency_s),
        ("--max-row-s", args.max_row_s),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(invalid(arg, value.to_string(), "must be finite and > 0"));
        }
    }
    Ok(())
}

/// Runs every row with every seed and arm count; writes the JSON report if asked.
pub fn run_eval_row(args: &EvalRowArgs) -> Result<RowEvalReport, RowEvalError> {
    validate(args)?;
    let mut arms_list = args.arms.clone();
    arms_list.sort_unstable();
    arms_list.dedup();
    let frames = FramePolicy {
        harvest_interval_ns: (args.frame_interval_s * 1e9) as u64,
        waiting_interval_ns: 500_000_000,
        latency_ns: (args.perception_latency_s * 1e9) as u64,
    };
    let mut runs = Vec::new();
    for name in &args.rows {
        let mut row = load_row(name)?;
        // The timing profile applies to every section's hardware (the row's world takes the
        // first section's vacuum settings).
        let mut arm_node = ArmNodeConfig::default();
        let mut pressure = PressureConfig::default();
        for scenario in &mut row.scenarios {
            arm_node = ArmNodeConfig::default();
            pressure = PressureConfig::default();
            apply_timing(scenario, &mut arm_node, &mut pressure, args.timing);
        }
        let Some(first) = row.scenarios.first() else {
            continue;
        };
        let pressure = pressure_for(&first.vacuum, pressure)
            .map_err(crate::harvest::HarvestEvalError::from)?;
        for k in 0..args.seeds {
            for &arms in &arms_list {
                let config = RowRunConfig {
                    name: row.file.name.clone(),
                    row: row.clone(),
                    seed: args.seed + u64::from(k),
                    arms,
                    policy: args.policy.kind(),
                    arm_node,
                    pressure,
                    detections: args.detections,
                    frames,
                    quiet_ns: args.stop_quiet_ms * 1_000_000,
                    max_row_s: args.max_row_s,
                };
                let outcome = run_row(&config)?;
                let report = RowRunReport::of(&outcome);
                tracing::info!(
                    row = %report.row,
                    seed = report.seed,
                    arms,
                    attempts = report.counts.attempts,
                    harvested = report.counts.harvested,
                    frames = report.frames,
                    "row done"
                );
                runs.push(report);
            }
        }
    }
    let mut by_arms: Vec<ArmSummary> = Vec::new();
    for &arms in &arms_list {
        let mut sum = ArmSummary {
            arms,
            ..ArmSummary::default()
        };
        for run in runs.iter().filter(|r| r.arms == arms) {
            sum.add(run);
        }
        by_arms.push(sum);
    }
    let report = RowEvalReport {
        rows: args.rows.clone(),
        seed: args.seed,
        seeds: args.seeds,
        detections: args.detections,
        frame_interval_s: args.frame_interval_s,
        list_failures: args.failures,
        runs,
        by_arms,
    };
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report).map_err(|e| RowEvalError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(path, text).map_err(|e| RowEvalError::Write {
            path: path.clone(),
            message: e.to_string(),
        })?;
    }
    Ok(report)
}
