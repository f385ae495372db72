//! The soak's findings: samples over time, what it did and what the stack answered, growth per
//! process over the second half of the run, and the verdicts.

use super::options::Bounds;
use super::procs::ProcessFigures;
use super::schedule::{BadInput, Expect};
use super::stack::StackSummary;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// One sample of every process and of the domain's shared memory.
#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    pub t_s: f64,
    /// Per launch name (and `supervisor`).
    pub processes: BTreeMap<String, ProcessFigures>,
    /// The domain's files in /dev/shm and the iceoryx2 root (harvest_ipc::cleanup::leftover_files).
    pub shm_entries: u64,
    pub shm_bytes: u64,
}

/// A SIGKILL the soak sent.
#[derive(Debug, Clone, Serialize)]
pub struct KillRecord {
    pub t_s: f64,
    pub process: String,
    /// None: the process was not running then (waiting for its restart).
    pub pid: Option<u32>,
    /// Why: `schedule` or `replant`.
    pub reason: &'static str,
    /// The pid that replaced it, and when it was seen.
    pub restarted_pid: Option<u32>,
    pub restart_seen_after_s: Option<f64>,
}

/// A process whose pid changed between two looks.
#[derive(Debug, Clone, Serialize)]
pub struct PidChange {
    pub t_s: f64,
    pub process: String,
    pub old_pid: u32,
    pub new_pid: u32,
    /// The old pid was one the soak killed.
    pub explained: bool,
}

/// One `harvest ctl` the soak ran.
#[derive(Debug, Clone, Serialize)]
pub struct CtlRecord {
    pub t_s: f64,
    pub args: Vec<String>,
    pub expect: Expect,
    pub exit_code: Option<i32>,
    /// The first line `ctl` printed.
    pub answer: String,
    pub outcome: Outcome,
}

/// How a command or bad input went.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// As expected (answered; refused where a refusal was expected; the stack went on).
    Ok,
    /// No answer while the executive was restarting after a kill of the soak.
    NoAnswerExplained,
    /// Not as expected.
    Unexpected,
}

/// One bad input fed.
#[derive(Debug, Clone, Serialize)]
pub struct InputRecord {
    pub t_s: f64,
    pub input: BadInput,
    pub detail: String,
    pub outcome: Outcome,
}

/// Restarts of one process.
#[derive(Debug, Clone, Serialize)]
pub struct RestartCount {
    pub process: String,
    /// The supervisor's count (its final summary; the pid changes seen when it printed none).
    pub restarts: u32,
    /// Caused by the soak's kills.
    pub explained: u32,
    pub unexplained: u32,
    /// The supervisor's last exit of the process.
    pub last_exit: String,
}

/// RSS and descriptors of one process over the run. The memory verdict judges private memory
/// (`RssAnon`), where a leak shows; the shared-memory pages a process has touched (`RssShmem`)
/// are shown beside it: they grow while a subscriber reads pool slots for the first time, up to
/// the size of the segments it maps (the domain's files, judged on their own).
#[derive(Debug, Clone, Serialize)]
pub struct Growth {
    pub process: String,
    pub rss_kib: [u64; 3],
    pub rss_max_kib: u64,
    /// `RssAnon` at start, middle, end, KiB.
    pub private_kib: [u64; 3],
    /// `RssShmem` at start, middle, end, KiB.
    pub shared_kib: [u64; 3],
    pub fds: [u64; 3],
    pub fds_max: u64,
    pub threads_end: u64,
    /// The instance judged: the one with the longest stretch in the second half.
    pub judged_pid: Option<u32>,
    /// Minutes of that stretch (after its first 30 s).
    pub judged_minutes: f64,
    /// Slope of `VmRSS` (all resident pages), KiB/min.
    pub rss_slope_kib_per_min: Option<f64>,
    /// Slope of `RssAnon` (private pages), KiB/min: the judged one.
    pub private_slope_kib_per_min: Option<f64>,
    /// Slope of `RssShmem` (shared-memory pages touched), KiB/min.
    pub shared_slope_kib_per_min: Option<f64>,
    pub fd_slope_per_min: Option<f64>,
}

/// Shared-memory files of the domain over the run.
#[derive(Debug, Clone, Serialize)]
pub struct ShmFigures {
    pub entries: [u64; 3],
    pub entries_min: u64,
    pub entries_max: u64,
    pub bytes_max: u64,
    pub slope_per_min: Option<f64>,
    /// Left after the stack stopped (should be 0).
    pub left_after_stop: u64,
}

/// Ground truth of the simulated world: apples in the bin, dropped.
#[derive(Debug, Clone, Default, Serialize)]
pub struct TruthFigures {
    /// Worlds the soak saw (1 + replants).
    pub worlds: u32,
    pub harvested: u32,
    pub dropped: u32,
}

/// Everything the soak reports.
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    pub domain: String,
    pub seed: u64,
    pub duration_s: f64,
    pub bounds: Bounds,
    pub console_port: u16,
    pub foxglove_port: u16,
    pub samples: Vec<Sample>,
    pub kills: Vec<KillRecord>,
    pub pid_changes: Vec<PidChange>,
    pub ctl: Vec<CtlRecord>,
    pub bad_inputs: Vec<InputRecord>,
    pub replants_s: Vec<f64>,
    pub restarts: Vec<RestartCount>,
    pub growth: Vec<Growth>,
    pub shm: ShmFigures,
    /// Sum over the recorder's instances of its last `dropped` heartbeat figure.
    pub recorder_drops: u64,
    pub recorder_instances: u32,
    pub truth: TruthFigures,
    /// `safety/violation` messages the soak received live.
    pub violations_seen: u64,
    /// `AttemptEnded` events the soak counted on `harvest/events` (each attempt, whatever the
    /// apple's id: the harvest summary of `harvest up` counts apples by id, and a vacuum
    /// supervisor restarted by a replant numbers the new world's apples from 1 again).
    pub attempts_ended: u32,
    pub harvested_events: u32,
    pub stack: StackSummary,
    /// `harvest up`'s exit status.
    pub stack_exit: String,
    /// Set when `harvest up` ended before the soak's end.
    pub stack_ended_early: Option<String>,
    pub recordings_bytes: u64,
    pub verdicts: Vec<Verdict>,
}

/// One judged property.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    pub what: String,
    pub passed: bool,
    pub detail: String,
}

impl SoakReport {
    pub fn passed(&self) -> bool {
        self.verdicts.iter().all(|v| v.passed)
    }

    pub fn unexplained_restarts(&self) -> u32 {
        self.restarts.iter().map(|r| r.unexplained).sum()
    }

    /// Judges the figures against the bounds.
    pub fn judge(&mut self) {
        let mut verdicts = Vec::new();
        let mut add = |what: &str, passed: bool, detail: String| {
            verdicts.push(Verdict {
                what: what.to_owned(),
                passed,
                detail,
            })
        };
        add(
            "stack ran the whole time",
            self.stack_ended_early.is_none(),
            self.stack_ended_early
                .clone()
                .unwrap_or_else(|| format!("exit {}", self.stack_exit)),
        );
        let unexplained = self.unexplained_restarts();
        let explained: u32 = self.restarts.iter().map(|r| r.explained).sum();
        add(
            "0 unexplained restarts",
            unexplained == 0,
            format!("{explained} explained, {unexplained} unexplained"),
        );
        let lost_kills = self
            .kills
            .iter()
            .filter(|k| k.pid.is_some() && k.restarted_pid.is_none())
            .count();
        add(
            "every killed process restarted",
            lost_kills == 0,
            format!(
                "{lost_kills} of {} kills not followed by a restart",
                self.kills.len()
            ),
        );
        let violations = self
            .stack
            .safety_violations
            .unwrap_or(self.violations_seen as u32);
        add(
            "0 safety violations",
            violations == 0 && self.violations_seen == 0,
            format!(
                "summary {}, seen live {}",
                self.stack
                    .safety_violations
                    .map_or("-".to_owned(), |n| n.to_string()),
                self.violations_seen
            ),
        );
        let unexpected_ctl = self
            .ctl
            .iter()
            .filter(|c| c.outcome == Outcome::Unexpected)
            .count();
        let unexpected_inputs = self
            .bad_inputs
            .iter()
            .filter(|c| c.outcome == Outcome::Unexpected)
            .count();
        add(
            "operator commands answered, bad inputs refused",
            unexpected_ctl == 0 && unexpected_inputs == 0,
            format!(
                "{unexpected_ctl} of {} commands, {unexpected_inputs} of {} bad inputs not as expected",
                self.ctl.len(),
                self.bad_inputs.len()
            ),
        );
        let bounds = self.bounds;
        let over_rss: Vec<String> = self
            .growth
            .iter()
            .filter(|g| {
                g.private_slope_kib_per_min
                    .is_some_and(|s| s > bounds.rss_slope_kib_per_min)
            })
            .map(|g| {
                format!(
                    "{} {:.0} KiB/min",
                    g.process,
                    g.private_slope_kib_per_min.unwrap_or(0.0)
                )
            })
            .collect();
        let judged = self
            .growth
            .iter()
            .filter(|g| g.private_slope_kib_per_min.is_some())
            .count();
        add(
            "private memory growth within bound",
            over_rss.is_empty(),
            format!(
                "RssAnon slope over the second half <= {} KiB/min; {judged} of {} processes judged{}",
                bounds.rss_slope_kib_per_min,
                self.growth.len(),
                if over_rss.is_empty() {
                    String::new()
                } else {
                    format!("; over: {}", over_rss.join(", "))
                }
            ),
        );
        let over_fds: Vec<String> = self
            .growth
            .iter()
            .filter(|g| {
                g.fd_slope_per_min
                    .is_some_and(|s| s > bounds.fd_slope_per_min)
            })
            .map(|g| format!("{} {:.2}/min", g.process, g.fd_slope_per_min.unwrap_or(0.0)))
            .collect();
        add(
            "descriptor growth within bound",
            over_fds.is_empty(),
            format!(
                "slope over the second half <= {}/min{}",
                bounds.fd_slope_per_min,
                if over_fds.is_empty() {
                    String::new()
                } else {
                    format!("; over: {}", over_fds.join(", "))
                }
            ),
        );
        let shm_slope = self.shm.slope_per_min.unwrap_or(0.0);
        add(
            "shared-memory files bounded, none left",
            shm_slope <= bounds.shm_slope_per_min && self.shm.left_after_stop == 0,
            format!(
                "slope {shm_slope:.2}/min (bound {}), {} left after the stop",
                bounds.shm_slope_per_min, self.shm.left_after_stop
            ),
        );
        self.verdicts = verdicts;
    }

    /// The text report.
    pub fn render(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "harvest soak: {:.0} s, seed {}, domain {}, {} samples (console :{}, foxglove :{})",
            self.duration_s,
            self.seed,
            self.domain,
            self.samples.len(),
            self.console_port,
            self.foxglove_port
        );
        let _ = writeln!(
            out,
            "actions: {} kills ({} by replant), {} operator commands, {} bad inputs, {} replants",
            self.kills.len(),
            self.kills.iter().filter(|k| k.reason == "replant").count(),
            self.ctl.len(),
            self.bad_inputs.len(),
            self.replants_s.len()
        );
        let _ = writeln!(
            out,
            "\nrestarts (supervisor's count; explained = after a kill of the soak):"
        );
        for r in &self.restarts {
            let _ = writeln!(
                out,
                "  {:<11} restarts {:>2}  explained {:>2}  unexplained {:>2}  last exit: {}",
                r.process, r.restarts, r.explained, r.unexplained, r.last_exit
            );
        }
        let restart_times: Vec<f64> = self
            .kills
            .iter()
            .filter_map(|k| k.restart_seen_after_s)
            .collect();
        if !restart_times.is_empty() {
            let max = restart_times.iter().cloned().fold(0.0, f64::max);
            let mean = restart_times.iter().sum::<f64>() / restart_times.len() as f64;
            let _ = writeln!(
                out,
                "  kill to new pid seen: mean {mean:.1} s, max {max:.1} s ({} kills)",
                restart_times.len()
            );
        }
        let _ = writeln!(
            out,
            "\nper process: RSS MiB start/middle/end (max), at the end private/shared MiB, fds \
start/middle/end (max), threads, slopes over the second half (instance judged): private (RssAnon, judged), shared-memory pages \
touched (RssShmem), descriptors:"
        );
        for g in &self.growth {
            let mib = |kib: u64| kib as f64 / 1024.0;
            let _ = writeln!(
                out,
                "  {:<11} {:>6.1} {:>6.1} {:>6.1} ({:>6.1}) {:>6.1}/{:<6.1}  {:>3} {:>3} {:>3} ({:>3})  thr {:>3}  {}",
                g.process,
                mib(g.rss_kib[0]),
                mib(g.rss_kib[1]),
                mib(g.rss_kib[2]),
                mib(g.rss_max_kib),
                mib(g.private_kib[2]),
                mib(g.shared_kib[2]),
                g.fds[0],
                g.fds[1],
                g.fds[2],
                g.fds_max,
                g.threads_end,
                match (
                    g.private_slope_kib_per_min,
                    g.shared_slope_kib_per_min,
                    g.fd_slope_per_min,
                ) {
                    (Some(private), Some(shared), Some(fds)) => format!(
                        "private {private:+.1} KiB/min, shared {shared:+.1} KiB/min, fds \
{fds:+.3}/min (pid {}, {:.1} min)",
                        g.judged_pid.unwrap_or(0),
                        g.judged_minutes
                    ),
                    _ => "not judged (no instance lived long enough in the second half)".to_owned(),
                }
            );
        }
        let _ = writeln!(
            out,
            "\nshared memory (domain files): start/middle/end {}/{}/{}, min {}, max {} ({:.1} MiB max), slope {}, left after stop {}",
            self.shm.entries[0],
            self.shm.entries[1],
            self.shm.entries[2],
            self.shm.entries_min,
            self.shm.entries_max,
            self.shm.bytes_max as f64 / 1048576.0,
            self.shm
                .slope_per_min
                .map_or("-".to_owned(), |s| format!("{s:+.2}/min")),
            self.shm.left_after_stop
        );
        let _ = writeln!(
            out,
            "recorder: {} drops over {} instance(s); recordings {:.2} GB",
            self.recorder_drops,
            self.recorder_instances,
            self.recordings_bytes as f64 / 1e9
        );
        let _ = writeln!(
            out,
            "harvest: {}",
            self.stack
                .harvest_line
                .as_deref()
                .unwrap_or("no harvest summary")
        );
        let _ = writeln!(
            out,
            "harvest/events: {} attempts ended, {} harvested (counted per attempt)",
            self.attempts_ended, self.harvested_events
        );
        let _ = writeln!(
            out,
            "ground truth (sim/ground_truth, {} world(s)): {} apples in the bin, {} dropped",
            self.truth.worlds, self.truth.harvested, self.truth.dropped
        );
        let _ = writeln!(
            out,
            "safety violations: {} in the summary, {} seen live",
            self.stack
                .safety_violations
                .map_or("-".to_owned(), |n| n.to_string()),
            self.violations_seen
        );
        const SHOWN_VIOLATIONS: usize = 10;
        for line in self.stack.violation_lines.iter().take(SHOWN_VIOLATIONS) {
            let _ = writeln!(out, "  VIOLATION {line}");
        }
        if self.stack.violation_lines.len() > SHOWN_VIOLATIONS {
            let _ = writeln!(
                out,
                "  ... {} more (--out keeps them all)",
                self.stack.violation_lines.len() - SHOWN_VIOLATIONS
            );
        }
        let refused = self.ctl.iter().filter(|c| c.exit_code == Some(1)).count();
        let _ = writeln!(
            out,
            "operator commands: {} sent, {} accepted, {} refused, {} unanswered while the executive restarted",
            self.ctl.len(),
            self.ctl.iter().filter(|c| c.exit_code == Some(0)).count(),
            refused,
            self.ctl
                .iter()
                .filter(|c| c.outcome == Outcome::NoAnswerExplained)
                .count()
        );
        for c in self.ctl.iter().filter(|c| c.outcome == Outcome::Unexpected) {
            let _ = writeln!(
                out,
                "  UNEXPECTED at {:.0} s: ctl {} -> exit {:?}: {}",
                c.t_s,
                c.args.join(" "),
                c.exit_code,
                c.answer
            );
        }
        for i in self
            .bad_inputs
            .iter()
            .filter(|i| i.outcome == Outcome::Unexpected)
        {
            let _ = writeln!(
                out,
                "  UNEXPECTED at {:.0} s: {:?}: {}",
                i.t_s, i.input, i.detail
            );
        }
        let _ = writeln!(out, "\nverdicts:");
        for v in &self.verdicts {
            let _ = writeln!(
                out,
                "  {} {}: {}",
                if v.passed { "PASS" } else { "FAIL" },
                v.what,
                v.detail
            );
        }
        out
    }
}

/// Least-squares slope of `(t_s, value)`, per minute; None under 3 points or no time spread.
pub fn slope_per_min(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean_t = points.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_v = points.iter().map(|p| p.1).sum::<f64>() / n;
    let var_t: f64 = points.iter().map(|p| (p.0 - mean_t).powi(2)).sum();
    if var_t <= f64::EPSILON {
        return None;
    }
    let cov: f64 = points.iter().map(|p| (p.0 - mean_t) * (p.1 - mean_v)).sum();
    Some(cov / var_t * 60.0)
}

/// How long after an instance's first sample its figures count (start-up allocations).
const INSTANCE_WARMUP_S: f64 = 30.0;

/// RSS and descriptors of `process` over `samples`; the slope of the instance with the longest
/// stretch in the second half (from `half_s`), at least `min_minutes` long.
pub fn growth_of(process: &str, samples: &[Sample], half_s: f64, min_minutes: f64) -> Growth {
    let series: Vec<(f64, ProcessFigures)> = samples
        .iter()
        .filter_map(|s| s.processes.get(process).map(|f| (s.t_s, *f)))
        .collect();
    let pick = |at: usize| series.get(at).map(|(_, f)| *f);
    let middle = series
        .iter()
        .position(|(t, _)| *t >= half_s)
        .unwrap_or(series.len().saturating_sub(1));
    let first = pick(0);
    let mid = pick(middle);
    let last = series.last().map(|(_, f)| *f);
    let of = |f: Option<ProcessFigures>, get: fn(&ProcessFigures) -> u64| f.map_or(0, |f| get(&f));
    // The instance with the most second-half samples after its own warm-up.
    let mut first_seen: BTreeMap<u32, f64> = BTreeMap::new();
    for (t, f) in &series {
        first_seen.entry(f.pid).or_insert(*t);
    }
    let mut by_pid: BTreeMap<u32, Vec<(f64, ProcessFigures)>> = BTreeMap::new();
    for (t, f) in &series {
        if *t >= half_s && *t >= first_seen[&f.pid] + INSTANCE_WARMUP_S {
            by_pid.entry(f.pid).or_default().push((*t, *f));
        }
    }
    let judged = by_pid
        .into_iter()
        .map(|(pid, points)| {
            let span = points.last().map_or(0.0, |p| p.0) - points.first().map_or(0.0, |p| p.0);
            (pid, points, span / 60.0)
        })
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .filter(|(_, _, minutes)| *minutes >= min_minutes);
    let slope_of = |points: &[(f64, ProcessFigures)], get: fn(&ProcessFigures) -> u64| {
        let series: Vec<(f64, f64)> = points.iter().map(|(t, f)| (*t, get(f) as f64)).collect();
        slope_per_min(&series)
    };
    let (judged_pid, judged_minutes, slopes) = match judged {
        Some((pid, points, minutes)) => (
            Some(pid),
            minutes,
            [
                slope_of(&points, |f| f.rss_kib),
                slope_of(&points, |f| f.private_kib),
                slope_of(&points, |f| f.shared_kib),
                slope_of(&points, |f| f.fds),
            ],
        ),
        None => (None, 0.0, [None; 4]),
    };
    let [rss_slope, private_slope, shared_slope, fd_slope] = slopes;
    let at_three = |get: fn(&ProcessFigures) -> u64| [of(first, get), of(mid, get), of(last, get)];
    Growth {
        process: process.to_owned(),
        rss_kib: at_three(|f| f.rss_kib),
        rss_max_kib: series.iter().map(|(_, f)| f.rss_kib).max().unwrap_or(0),
        private_kib: at_three(|f| f.private_kib),
        shared_kib: at_three(|f| f.shared_kib),
        fds: at_three(|f| f.fds),
        fds_max: series.iter().map(|(_, f)| f.fds).max().unwrap_or(0),
        threads_end: of(last, |f| f.threads),
        judged_pid,
        judged_minutes,
        rss_slope_kib_per_min: rss_slope,
        private_slope_kib_per_min: private_slope,
        shared_slope_kib_per_min: shared_slope,
        fd_slope_per_min: fd_slope,
    }
}

/// The domain's shared-memory files over the samples; `left_after_stop` counted after the stop.
pub fn shm_of(samples: &[Sample], half_s: f64, left_after_stop: u64) -> ShmFigures {
    let middle = samples
        .iter()
        .position(|s| s.t_s >= half_s)
        .unwrap_or(samples.len().saturating_sub(1));
    let at = |i: usize| samples.get(i).map_or(0, |s| s.shm_entries);
    let second_half: Vec<(f64, f64)> = samples
        .iter()
        .filter(|s| s.t_s >= half_s)
        .map(|s| (s.t_s, s.shm_entries as f64))
        .collect();
    ShmFigures {
        entries: [
            at(0),
            at(middle),
            samples.last().map_or(0, |s| s.shm_entries),
        ],
        entries_min: samples.iter().map(|s| s.shm_entries).min().unwrap_or(0),
        entries_max: samples.iter().map(|s| s.shm_entries).max().unwrap_or(0),
        bytes_max: samples.iter().map(|s| s.shm_bytes).max().unwrap_or(0),
        slope_per_min: slope_per_min(&second_half),
        left_after_stop,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sample of arm1 whose private memory is `rss_kib` and whose shared pages are flat.
    fn sample(t_s: f64, pid: u32, rss_kib: u64, fds: u64) -> Sample {
        let mut processes = BTreeMap::new();
        processes.insert(
            "arm1".to_owned(),
            ProcessFigures {
                pid,
                rss_kib: rss_kib + 4_000,
                private_kib: rss_kib,
                shared_kib: 4_000,
                fds,
                threads: 3,
            },
        );
        Sample {
            t_s,
            processes,
            shm_entries: 100,
            shm_bytes: 1 << 20,
        }
    }

    #[test]
    fn slope_of_a_line_is_its_rate_per_minute() {
        let points: Vec<(f64, f64)> = (0..10)
            .map(|i| (i as f64 * 6.0, 100.0 + i as f64))
            .collect();
        let slope = slope_per_min(&points).expect("slope");
        assert!((slope - 10.0).abs() < 1e-9, "{slope}");
        assert_eq!(slope_per_min(&points[..2]), None);
        assert_eq!(slope_per_min(&[(1.0, 1.0), (1.0, 2.0), (1.0, 3.0)]), None);
    }

    #[test]
    fn growth_judges_the_long_lived_instance_after_its_warm_up() {
        // pid 1 for 0-300 s (flat), killed; pid 2 from 305 s, growing 100 KiB/min; a short pid 3
        // at the end would not be judged.
        let mut samples: Vec<Sample> = (0..=60)
            .map(|i| sample(i as f64 * 5.0, 1, 50_000, 20))
            .collect();
        samples.extend((61..=240).map(|i| {
            let t = i as f64 * 5.0;
            sample(t, 2, 40_000 + ((t - 305.0) / 60.0 * 100.0) as u64, 22)
        }));
        let growth = growth_of("arm1", &samples, 600.0, 2.0);
        assert_eq!(growth.judged_pid, Some(2));
        let slope = growth.private_slope_kib_per_min.expect("judged");
        assert!((slope - 100.0).abs() < 2.0, "{slope}");
        let rss_slope = growth.rss_slope_kib_per_min.expect("judged");
        assert!((rss_slope - 100.0).abs() < 2.0, "{rss_slope}");
        assert_eq!(growth.shared_slope_kib_per_min, Some(0.0));
        assert_eq!(growth.fd_slope_per_min, Some(0.0));
        assert_eq!(growth.private_kib[0], 50_000);
        assert_eq!(growth.rss_kib[0], 54_000);
        assert_eq!(growth.rss_max_kib, 54_000);
        assert_eq!(growth.fds_max, 22);
        let none = growth_of("arm1", &samples, 1190.0, 2.0);
        assert_eq!(none.judged_pid, None);
        assert_eq!(growth_of("absent", &samples, 600.0, 2.0).rss_kib, [0, 0, 0]);
    }

    #[test]
    fn shm_figures_over_the_run() {
        let samples: Vec<Sample> = (0..20).map(|i| sample(i as f64 * 60.0, 1, 1, 1)).collect();
        let shm = shm_of(&samples, 600.0, 0);
        assert_eq!(shm.entries, [100, 100, 100]);
        assert_eq!(shm.slope_per_min, Some(0.0));
    }
}
