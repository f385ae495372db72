//! The harvest as a reader of `harvest/events` sees it: one line per per-apple event worth
//! showing (assigned, phases, result, failure cause, refused targets) and, at the end, the
//! summary ([dual-arm sec. 4.2, Table 2] definitions, as in `harvest eval harvest`):
//!
//! - an *attempt* is one target taken by an arm until the arm is idle again (the arm's
//!   `AttemptEnded`), or a target dispatched and never taken (the vacuum supervisor's
//!   `DispatchTimedOut`);
//! - *attempted apples* are the apples (vacuum supervisor ids) at least one attempt aimed at;
//!   *harvested* ones had an attempt that released them at the drop-off; *first-attempt
//!   successes* were harvested by their first attempt;
//! - the *duration* runs from the first assignment to the end of the last attempt; *seconds per
//!   apple* and *per attempt* divide it by the harvested apples and by the attempts
//!   ([`CycleRates`], shared with the evaluation).
//!
//! Along a row (the executive's stop-and-go cycle) each `StopFinished` line gets the failed
//! attempts by cause that ended during that stop (after the previous stop's event, by the
//! events' stamps on the one monotonic clock), and the row summary those of the whole row: the
//! same cause labels as the summary's "failed attempts", and beside them the paper's Table 3
//! categories the live stack can name ([`table3`]).
//!
//! "Harvested" is the arm's account (the apple was released at the drop-off with the seal
//! held): the live stack has no ground truth. The evaluation scores against the simulator's.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod table3;

use std::collections::BTreeMap;
use std::fmt::{self, Write as _};

use harvest_ipc::payloads::{
    ArmPhase, HarvestCause, HarvestEvent, HarvestEventKind, HarvestEventSource,
};
use serde::Serialize;

/// Success rate and cycle times from counts and a duration (Table 2 and Fig. 12 definitions).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct CycleRates {
    /// `harvested / attempted` apples.
    pub success_rate: Option<f64>,
    /// `duration / harvested apples`, s.
    pub seconds_per_apple: Option<f64>,
    /// `duration / attempts`, s (the field's "cycle time per attempt").
    pub seconds_per_attempt: Option<f64>,
}

impl CycleRates {
    /// The rates of `apples_harvested` out of `apples_attempted` apples in `attempts` attempts
    /// over `duration_s` seconds; a rate whose denominator is zero is `None`.
    pub fn new(
        apples_attempted: u32,
        apples_harvested: u32,
        attempts: u32,
        duration_s: f64,
    ) -> Self {
        Self {
            success_rate: (apples_attempted > 0)
                .then(|| f64::from(apples_harvested) / f64::from(apples_attempted)),
            seconds_per_apple: (apples_harvested > 0)
                .then(|| duration_s / f64::from(apples_harvested)),
            seconds_per_attempt: (attempts > 0).then(|| duration_s / f64::from(attempts)),
        }
    }
}

/// One ended attempt.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AttemptEntry {
    /// Arm number (1 or 2).
    pub arm: u8,
    /// The vacuum supervisor's apple id.
    pub apple_id: u32,
    /// When the target was assigned (or, if the assignment was not seen, taken), ns.
    pub start_ns: u64,
    /// When the attempt ended, ns.
    pub end_ns: u64,
    /// The apple was released at the drop-off.
    pub harvested: bool,
    /// Why not.
    pub cause: HarvestCause,
}

impl AttemptEntry {
    /// From assignment to the end of the attempt, s.
    pub fn duration_s(&self) -> f64 {
        self.end_ns.saturating_sub(self.start_ns) as f64 * 1e-9
    }
}

/// Per apple.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct AppleEntry {
    attempts: u32,
    harvested: bool,
    first_attempt_harvested: bool,
}

/// The summary of a harvest.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct HarvestLogSummary {
    /// Apples at least one attempt aimed at.
    pub apples_attempted: u32,
    /// Apples released at the drop-off.
    pub apples_harvested: u32,
    /// Apples harvested by their first attempt.
    pub first_attempt_successes: u32,
    /// Attempts.
    pub attempts: u32,
    /// Failed attempts by cause label.
    pub failure_causes: BTreeMap<&'static str, u32>,
    /// Failed attempts by category of [dual-arm Table 3], as far as the live stack can tell
    /// ([`table3::table3_category`]).
    pub failure_categories: BTreeMap<&'static str, u32>,
    /// Targets the arms refused for good, by cause label.
    pub rejected_targets: BTreeMap<&'static str, u32>,
    /// From the first assignment to the end of the last attempt, s.
    pub duration_s: f64,
    /// Rates over `duration_s`.
    pub rates: CycleRates,
    /// Mean time from assignment to the end of an attempt, s.
    pub mean_attempt_s: Option<f64>,
    /// The vacuum supervisor reported that nothing is left to pick.
    pub complete: bool,
    /// Times an arm braked because its encoder feedback was missing or late.
    pub feedback_stalls: u32,
    /// The stops of a row the executive's stop-and-go cycle finished (their lines).
    pub stops: Vec<String>,
    /// The row's own summary line, once its last stop was finished.
    pub row: Option<String>,
}

/// `label count, label count` (or `none`), in label order.
fn cause_list(map: &BTreeMap<&'static str, u32>) -> String {
    if map.is_empty() {
        return "none".to_owned();
    }
    map.iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn opt(value: Option<f64>, digits: usize) -> String {
    value.map_or_else(|| "-".to_owned(), |v| format!("{v:.digits$}"))
}

impl fmt::Display for HarvestLogSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "harvest summary: attempted {}, harvested {} (success {} %), first-attempt successes \
             {}{}",
            self.apples_attempted,
            self.apples_harvested,
            opt(self.rates.success_rate.map(|r| r * 100.0), 1),
            self.first_attempt_successes,
            if self.complete {
                ", complete"
            } else {
                ", not complete"
            }
        )?;
        writeln!(
            f,
            "  attempts {}, time {:.1} s: {} s/apple, {} s/attempt, mean attempt {} s",
            self.attempts,
            self.duration_s,
            opt(self.rates.seconds_per_apple, 2),
            opt(self.rates.seconds_per_attempt, 2),
            opt(self.mean_attempt_s, 2)
        )?;
        if !self.failure_causes.is_empty() {
            writeln!(
                f,
                "  failed attempts: {}; by Table 3 category: {}",
                cause_list(&self.failure_causes),
                cause_list(&self.failure_categories)
            )?;
        }
        if !self.rejected_targets.is_empty() {
            writeln!(
                f,
                "  rejected targets: {}",
                cause_list(&self.rejected_targets)
            )?;
        }
        if let Some(row) = &self.row {
            writeln!(
                f,
                "row summary ({} stops): {row}, failed: {}; by Table 3 category: {}",
                self.stops.len(),
                cause_list(&self.failure_causes),
                cause_list(&self.failure_categories)
            )?;
        }
        if self.feedback_stalls > 0 {
            writeln!(
                f,
                "  arms braked {} time(s) for missing or late encoder feedback",
                self.feedback_stalls
            )?;
        }
        Ok(())
    }
}

/// Collects `harvest/events` into per-apple lines and a summary.
#[derive(Debug, Clone)]
pub struct HarvestLog {
    origin_ns: u64,
    /// Assignments not ended yet: (arm, apple) -> assigned at, ns. Keyed by both, as events of
    /// different processes arrive interleaved (an arm's end of attempt may arrive after the
    /// vacuum supervisor already assigned that arm its next apple).
    assigned: BTreeMap<(u8, u32), u64>,
    /// Ticks at which an arm's feedback went invalid (the arm braked).
    feedback_stalls: u32,
    attempts: Vec<AttemptEntry>,
    apples: BTreeMap<u32, AppleEntry>,
    rejected: BTreeMap<&'static str, u32>,
    first_assigned_ns: Option<u64>,
    complete: bool,
    stops: Vec<String>,
    /// Stamp of the last `StopFinished`: attempts that ended after it belong to the next stop.
    last_stop_ns: Option<u64>,
    row: Option<String>,
}

impl HarvestLog {
    /// An empty log; event lines show times relative to `origin_ns` (stack clock).
    pub fn new(origin_ns: u64) -> Self {
        Self {
            origin_ns,
            assigned: BTreeMap::new(),
            feedback_stalls: 0,
            attempts: Vec::new(),
            apples: BTreeMap::new(),
            rejected: BTreeMap::new(),
            first_assigned_ns: None,
            complete: false,
            stops: Vec::new(),
            last_stop_ns: None,
            row: None,
        }
    }

    /// The attempts ended so far.
    pub fn attempts(&self) -> &[AttemptEntry] {
        &self.attempts
    }

    /// True once the vacuum supervisor reported that nothing is left to pick.
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// True once the executive's stop-and-go cycle finished the row's last stop.
    pub fn row_done(&self) -> bool {
        self.row.is_some()
    }

    /// Takes one event; returns the line to show for it, if any.
    pub fn on_event(&mut self, event: &HarvestEvent) -> Option<String> {
        // An event of a kind this build does not know (a newer publisher) shows no line.
        let kind = event.kind.get().ok()?;
        let t_ns = event.header.capture_ns;
        let arm = match event.arm_id {
            1 | 2 => Some(event.arm_id),
            _ => None,
        };
        let cause = event.cause.get().unwrap_or(HarvestCause::Other);
        let text = match kind {
            HarvestEventKind::Assigned => {
                let arm = arm?;
                self.assigned.insert((arm, event.apple_id), t_ns);
                self.first_assigned_ns.get_or_insert(t_ns);
                self.complete = false;
                let [x, y, z] = event.position_in_robot_m;
                format!("assigned at ({x:.3}, {y:.3}, {z:.3}) m")
            }
            HarvestEventKind::TargetAccepted => "target accepted, approaching".to_owned(),
            HarvestEventKind::TargetRejected => {
                let retry = event.harvested != 0;
                if !retry {
                    *self.rejected.entry(cause.label()).or_insert(0) += 1;
                }
                format!(
                    "target rejected ({}{}): {}",
                    cause.label(),
                    if retry { ", will retry" } else { "" },
                    event.reason
                )
            }
            HarvestEventKind::PhaseChanged => {
                let phase = event.phase.get().ok()?;
                if phase == ArmPhase::Idle {
                    return None;
                }
                format!("phase {phase:?}")
            }
            HarvestEventKind::Attached => "attached (seal)".to_owned(),
            HarvestEventKind::CycleStep if cause == HarvestCause::NoFeedback => {
                // Counted, not shown: on a loaded host these come often and say little.
                self.feedback_stalls += 1;
                return None;
            }
            HarvestEventKind::CycleStep if cause != HarvestCause::None => {
                format!("{} ({})", event.reason, cause.label())
            }
            HarvestEventKind::AttemptEnded => {
                let arm = arm?;
                let harvested = event.harvested != 0;
                let start_ns = self.assigned.remove(&(arm, event.apple_id)).unwrap_or(t_ns);
                let cause = if harvested {
                    HarvestCause::None
                } else if cause == HarvestCause::None {
                    HarvestCause::Other
                } else {
                    cause
                };
                let entry = self.end_attempt(
                    event.arm_id,
                    event.apple_id,
                    start_ns,
                    t_ns,
                    harvested,
                    cause,
                );
                if harvested {
                    format!("HARVESTED ({:.2} s from assignment)", entry.duration_s())
                } else {
                    format!(
                        "FAILED: {} ({:.2} s from assignment)",
                        cause.label(),
                        entry.duration_s()
                    )
                }
            }
            HarvestEventKind::DispatchTimedOut => {
                let arm = arm?;
                let start_ns = self.assigned.remove(&(arm, event.apple_id)).unwrap_or(t_ns);
                self.end_attempt(
                    event.arm_id,
                    event.apple_id,
                    start_ns,
                    t_ns,
                    false,
                    HarvestCause::TargetNotTaken,
                );
                format!("FAILED: {}", HarvestCause::TargetNotTaken.label())
            }
            HarvestEventKind::EmergencyStop => {
                // Both processes report it; show the vacuum supervisor's (once for the stack).
                if event.source != HarvestEventSource::Vacuum {
                    return None;
                }
                format!("EMERGENCY STOP {}", event.reason)
            }
            HarvestEventKind::HarvestComplete => {
                self.complete = true;
                "harvest complete: nothing left to pick".to_owned()
            }
            HarvestEventKind::StopFinished => {
                let failures = self.failures_since(self.last_stop_ns, t_ns);
                self.last_stop_ns = Some(t_ns);
                let text = format!(
                    "{}, failed: {}",
                    event.reason.as_str(),
                    cause_list(&failures)
                );
                self.stops.push(text.clone());
                text
            }
            HarvestEventKind::RowFinished => {
                let text = event.reason.as_str().to_owned();
                self.row = Some(text.clone());
                format!("row done: {text}")
            }
            _ => return None,
        };
        Some(self.line(event, &text))
    }

    /// Failed attempts by cause label that ended after `after_ns` (all when `None`) and at or
    /// before `until_ns`.
    fn failures_since(&self, after_ns: Option<u64>, until_ns: u64) -> BTreeMap<&'static str, u32> {
        let mut failures = BTreeMap::new();
        for attempt in self.attempts.iter().filter(|a| {
            !a.harvested && after_ns.is_none_or(|after| a.end_ns > after) && a.end_ns <= until_ns
        }) {
            *failures.entry(attempt.cause.label()).or_insert(0) += 1;
        }
        failures
    }

    fn end_attempt(
        &mut self,
        arm: u8,
        apple_id: u32,
        start_ns: u64,
        end_ns: u64,
        harvested: bool,
        cause: HarvestCause,
    ) -> AttemptEntry {
        let entry = AttemptEntry {
            arm,
            apple_id,
            start_ns,
            end_ns,
            harvested,
            cause,
        };
        self.attempts.push(entry);
        let apple = self.apples.entry(apple_id).or_default();
        apple.attempts += 1;
        if harvested && !apple.harvested {
            apple.harvested = true;
            apple.first_attempt_harvested = apple.attempts == 1;
        }
        entry
    }

    fn line(&self, event: &HarvestEvent, text: &str) -> String {
        let t_s = event.header.capture_ns.saturating_sub(self.origin_ns) as f64 * 1e-9;
        let mut line = format!("[{t_s:8.3} s] ");
        match event.arm_id {
            1 | 2 => {
                let _ = write!(line, "arm{} ", event.arm_id);
            }
            _ => line.push_str("     "),
        }
        if event.apple_id != 0 {
            let _ = write!(line, "apple {:<4} ", event.apple_id);
        }
        line.push_str(text);
        line
    }

    /// The summary so far.
    pub fn summary(&self) -> HarvestLogSummary {
        let attempts = self.attempts.len() as u32;
        let apples_attempted = self.apples.len() as u32;
        let apples_harvested = self.apples.values().filter(|a| a.harvested).count() as u32;
        let first_attempt_successes = self
            .apples
            .values()
            .filter(|a| a.first_attempt_harvested)
            .count() as u32;
        let mut failure_causes = BTreeMap::new();
        let mut failure_categories = BTreeMap::new();
        for a in self.attempts.iter().filter(|a| !a.harvested) {
            *failure_causes.entry(a.cause.label()).or_insert(0) += 1;
            *failure_categories
                .entry(table3::table3_category(a.cause))
                .or_insert(0) += 1;
        }
        let last_end_ns = self.attempts.iter().map(|a| a.end_ns).max();
        let duration_s = match (self.first_assigned_ns, last_end_ns) {
            (Some(first), Some(last)) => last.saturating_sub(first) as f64 * 1e-9,
            _ => 0.0,
        };
        let mean_attempt_s = (attempts > 0).then(|| {
            self.attempts
                .iter()
                .map(AttemptEntry::duration_s)
                .sum::<f64>()
                / f64::from(attempts)
        });
        HarvestLogSummary {
            apples_attempted,
            apples_harvested,
            first_attempt_successes,
            attempts,
            failure_causes,
            failure_categories,
            rejected_targets: self.rejected.clone(),
            duration_s,
            rates: CycleRates::new(apples_attempted, apples_harvested, attempts, duration_s),
            mean_attempt_s,
            complete: self.complete,
            stops: self.stops.clone(),
            row: self.row.clone(),
            feedback_stalls: self.feedback_stalls,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: u64 = 1_000_000_000;

    fn event(
        t_s: u64,
        source: HarvestEventSource,
        kind: HarvestEventKind,
        arm: u8,
        apple: u32,
    ) -> HarvestEvent {
        HarvestEvent::new(t_s * S, source, kind, arm, apple)
    }

    fn ended(t_s: u64, arm: u8, apple: u32, cause: Option<HarvestCause>) -> HarvestEvent {
        let source = HarvestEventSource::arm(arm).expect("arm");
        let mut e = event(t_s, source, HarvestEventKind::AttemptEnded, arm, apple);
        match cause {
            None => e.harvested = 1,
            Some(cause) => e.cause.set(cause),
        }
        e
    }

    fn assigned(t_s: u64, arm: u8, apple: u32) -> HarvestEvent {
        event(
            t_s,
            HarvestEventSource::Vacuum,
            HarvestEventKind::Assigned,
            arm,
            apple,
        )
    }

    fn field(t_s: u64, kind: HarvestEventKind, line: &str) -> HarvestEvent {
        let mut e = event(t_s, HarvestEventSource::Field, kind, 0, 0);
        e.reason = harvest_ipc::FixedString::new(line);
        e
    }

    #[test]
    fn each_stop_line_gets_the_failures_of_its_own_stop() {
        let mut log = HarvestLog::new(0);
        let trace = [
            assigned(1, 1, 1),
            ended(2, 1, 1, Some(HarvestCause::NoAttachment)),
            assigned(2, 2, 2),
            ended(3, 2, 2, Some(HarvestCause::AppleLost)),
            assigned(3, 1, 1),
            ended(4, 1, 1, Some(HarvestCause::NoAttachment)),
            field(5, HarvestEventKind::StopFinished, "stop 1"),
            assigned(6, 1, 3),
            ended(7, 1, 3, None),
            field(8, HarvestEventKind::StopFinished, "stop 2"),
            assigned(9, 1, 4),
            ended(10, 1, 4, Some(HarvestCause::ApproachTimeout)),
            field(11, HarvestEventKind::StopFinished, "stop 3"),
            field(11, HarvestEventKind::RowFinished, "3 stops"),
        ];
        let lines: Vec<String> = trace.iter().filter_map(|e| log.on_event(e)).collect();
        let stops: Vec<&String> = lines.iter().filter(|l| l.contains("stop ")).collect();
        assert_eq!(stops.len(), 3, "{lines:?}");
        assert!(
            stops[0].ends_with("stop 1, failed: apple_lost 1, no_attachment 2"),
            "{stops:?}"
        );
        assert!(stops[1].ends_with("stop 2, failed: none"), "{stops:?}");
        assert!(
            stops[2].ends_with("stop 3, failed: approach_timeout 1"),
            "{stops:?}"
        );
        let summary = log.summary().to_string();
        assert!(
            summary.contains(
                "row summary (3 stops): 3 stops, failed: apple_lost 1, approach_timeout 1, \
                 no_attachment 2"
            ),
            "{summary}"
        );
    }

    #[test]
    fn rates_of_known_counts() {
        let r = CycleRates::new(4, 3, 5, 12.0);
        assert_eq!(r.success_rate, Some(0.75));
        assert_eq!(r.seconds_per_apple, Some(4.0));
        assert_eq!(r.seconds_per_attempt, Some(2.4));
        let none = CycleRates::new(0, 0, 0, 0.0);
        assert_eq!(none, CycleRates::default());
    }

    #[test]
    fn a_known_trace_gives_known_counts_and_times() {
        let mut log = HarvestLog::new(10 * S);
        let trace = [
            assigned(10, 1, 1),
            assigned(11, 2, 2),
            ended(13, 1, 1, None),                             // 3 s, harvested
            ended(14, 2, 2, Some(HarvestCause::NoAttachment)), // 3 s, failed
            assigned(14, 1, 3),
            assigned(15, 2, 2),
            ended(17, 1, 3, None), // 3 s, harvested
            ended(18, 2, 2, None), // 3 s, second attempt
            assigned(18, 1, 4),
            event(
                21,
                HarvestEventSource::Vacuum,
                HarvestEventKind::DispatchTimedOut,
                1,
                4,
            ),
        ];
        let lines: Vec<String> = trace.iter().filter_map(|e| log.on_event(e)).collect();
        assert_eq!(lines.len(), trace.len());
        assert!(
            lines[2].contains("arm1 apple 1") && lines[2].contains("HARVESTED"),
            "{lines:?}"
        );
        assert!(lines[3].contains("FAILED: no_attachment"), "{lines:?}");
        assert!(lines[0].starts_with("[   0.000 s]"), "{lines:?}");
        let s = log.summary();
        assert_eq!(s.attempts, 5);
        assert_eq!(s.apples_attempted, 4);
        assert_eq!(s.apples_harvested, 3);
        assert_eq!(s.first_attempt_successes, 2);
        assert_eq!(s.duration_s, 11.0);
        assert_eq!(s.rates.seconds_per_apple, Some(11.0 / 3.0));
        assert_eq!(s.rates.seconds_per_attempt, Some(11.0 / 5.0));
        assert_eq!(s.mean_attempt_s, Some(3.0));
        assert_eq!(s.failure_causes.get("no_attachment"), Some(&1));
        assert_eq!(s.failure_causes.get("target_not_taken"), Some(&1));
        assert_eq!(
            s.failure_categories.get("sealing or perception (no seal)"),
            Some(&1)
        );
        assert_eq!(s.failure_categories.get("other"), Some(&1));
        assert!(
            s.to_string()
                .contains("by Table 3 category: other 1, sealing or perception (no seal) 1"),
            "{s}"
        );
        assert!(!s.complete);
        let text = s.to_string();
        assert!(text.contains("attempted 4, harvested 3"), "{text}");
        let done = event(
            22,
            HarvestEventSource::Vacuum,
            HarvestEventKind::HarvestComplete,
            0,
            0,
        );
        assert!(log.on_event(&done).is_some());
        assert!(log.summary().complete);
    }

    #[test]
    fn an_end_arriving_after_the_next_assignment_keeps_both_times() {
        let mut log = HarvestLog::new(0);
        log.on_event(&assigned(1, 2, 5));
        // The vacuum supervisor's next assignment arrives before the arm's end of attempt.
        log.on_event(&assigned(6, 2, 10));
        let line = log.on_event(&ended(5, 2, 5, None)).expect("line");
        assert!(line.contains("4.00 s from assignment"), "{line}");
        log.on_event(&ended(9, 2, 10, None));
        let durations: Vec<f64> = log
            .attempts()
            .iter()
            .map(AttemptEntry::duration_s)
            .collect();
        assert_eq!(durations, [4.0, 3.0]);
        let mut stall = event(
            9,
            HarvestEventSource::Arm1,
            HarvestEventKind::CycleStep,
            1,
            0,
        );
        stall.cause.set(HarvestCause::NoFeedback);
        assert!(log.on_event(&stall).is_none());
        assert_eq!(log.summary().feedback_stalls, 1);
    }

    #[test]
    fn refusals_are_counted_once_and_retries_not() {
        let mut log = HarvestLog::new(0);
        let mut rejected = event(
            1,
            HarvestEventSource::Arm1,
            HarvestEventKind::TargetRejected,
            1,
            7,
        );
        rejected.cause.set(HarvestCause::NonFinite);
        let line = log.on_event(&rejected).expect("line");
        assert!(line.contains("target rejected (non_finite)"), "{line}");
        let mut retry = rejected;
        retry.cause.set(HarvestCause::ClearanceConflict);
        retry.harvested = 1;
        assert!(log.on_event(&retry).expect("line").contains("will retry"));
        let s = log.summary();
        assert_eq!(s.rejected_targets.get("non_finite"), Some(&1));
        assert_eq!(s.rejected_targets.len(), 1);
        assert_eq!(s.attempts, 0);
        // Valve and re-plan events make no line.
        let opened = event(
            2,
            HarvestEventSource::Vacuum,
            HarvestEventKind::ValveOpened,
            1,
            7,
        );
        assert!(log.on_event(&opened).is_none());
    }
}
