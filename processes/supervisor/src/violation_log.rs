//! [`ViolationLog`]: the safety monitor's findings read from `safety/violation`, each once.
//!
//! The monitor sends a stop request again until it sees the stop engaged, so one finding can
//! arrive several times; the log keeps the first copy ([`SafetyViolation::same_finding`]).

use harvest_ipc::payloads::SafetyViolation;

/// One `safety/violation` message in words, as the summary names it.
pub fn violation_line(violation: &SafetyViolation) -> String {
    let rule = match violation.rule.get() {
        Ok(rule) => format!("{rule:?}"),
        Err(unknown) => unknown.to_string(),
    };
    let action = if violation.requests_stop() {
        "protective stop requested"
    } else {
        "reported only"
    };
    format!("{rule}: {} ({action})", violation.description.as_str())
}

/// Distinct findings in the order received, and how many copies were left out.
#[derive(Debug, Clone, Default)]
pub struct ViolationLog {
    lines: Vec<String>,
    last: Option<SafetyViolation>,
    repeats: u64,
}

impl ViolationLog {
    /// Takes one message; returns its line when it is a new finding, `None` for a copy of the
    /// finding received just before.
    pub fn record(&mut self, violation: &SafetyViolation) -> Option<&str> {
        if self.last.is_some_and(|last| last.same_finding(violation)) {
            self.repeats += 1;
            return None;
        }
        self.last = Some(*violation);
        self.lines.push(violation_line(violation));
        self.lines.last().map(String::as_str)
    }

    /// The distinct findings, in words.
    pub fn lines(&self) -> &[String] {
        &self.lines
    }

    /// Copies of a finding left out (re-sent stop requests).
    pub fn repeats(&self) -> u64 {
        self.repeats
    }

    /// The distinct findings, in words.
    pub fn into_lines(self) -> Vec<String> {
        self.lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::{ViolationAction, ViolationRule};

    fn finding(violated_ns: u64, arm_id: u8) -> SafetyViolation {
        SafetyViolation {
            violated_ns,
            rule: ViolationRule::MovedDuringEmergencyStop.into(),
            action: ViolationAction::Stop.into(),
            arm_id,
            ..SafetyViolation::default()
        }
    }

    #[test]
    fn resent_requests_count_once_and_new_findings_each_count() {
        let mut log = ViolationLog::default();
        let first = finding(10, 2);
        assert!(log.record(&first).is_some());
        for seq in 1..50 {
            let mut resent = first;
            resent.header.msg_seq = seq;
            assert_eq!(log.record(&resent), None);
        }
        assert!(log.record(&finding(10, 1)).is_some());
        assert!(log.record(&finding(11, 1)).is_some());
        assert_eq!(log.lines().len(), 3);
        assert_eq!(log.repeats(), 49);
        assert!(log.lines()[0].starts_with("MovedDuringEmergencyStop: "));
        assert!(log.lines()[0].ends_with("(protective stop requested)"));
    }
}
