//! A safety rule the independent monitor (`harvest monitor`) found broken on the live channels,
//! and whether it asks the executive to engage the protective stop.
//!
//! The monitor is the channel's one writer; the executive (the e-stop's one writer) reads it and
//! engages `safety/emergency_stop` when `action` is [`ViolationAction::Stop`] (or unknown: the
//! safe side). Nothing on this channel can release the stop: release stays an operator command.

use crate::fixed_string::FixedString;
use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Capacity of [`SafetyViolation::description`], bytes.
pub const VIOLATION_TEXT_BYTES: usize = 160;

/// The rule broken (the variants of `harvest_safety::safety_monitor::Violation`).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum ViolationRule {
    /// A valve opened while the other arm's valve was open with no seal.
    OpenedBesideUnsealed = 1,
    /// Both valves open with neither cup sealed for longer than one control period.
    BothOpenUnsealed = 2,
    /// A valve not closed by its deadline after a failure on its arm.
    FailureNotClosed = 3,
    /// A joint command outside its limits (or not finite).
    JointOutOfLimits = 4,
    /// A valve open during the emergency stop.
    ValveOpenDuringEmergencyStop = 5,
    /// A joint set-point sent during the emergency stop.
    MovedDuringEmergencyStop = 6,
    /// The end-effectors closer than the clearance.
    EndEffectorsTooClose = 7,
    /// No rule broken: `harvest monitor --engage-stop-after` asks for a stop to measure the
    /// stack's reaction.
    ReactionMeasurement = 8,
}

/// What the monitor asks for.
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum ViolationAction {
    /// Reported only (`--on-violation report`).
    Report = 0,
    /// The protective stop must be engaged (`--on-violation stop`).
    Stop = 1,
}

/// One violation (`safety/violation`). `header.capture_ns` is when the monitor found it.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.SafetyViolation.v1")]
pub struct SafetyViolation {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// When the rule was broken, as the monitor's trace dates it, ns (monotonic clock).
    pub violated_ns: u64,
    /// The rule.
    pub rule: WireCode<ViolationRule>,
    /// What the monitor asks for.
    pub action: WireCode<ViolationAction>,
    /// Arm 1 or 2 the rule concerns, 0 for both or none.
    pub arm_id: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 5],
    /// In words, as `harvest monitor` prints it.
    pub description: FixedString<VIOLATION_TEXT_BYTES>,
}

impl SafetyViolation {
    /// True unless the monitor only reports it: an unknown action code asks for the stop (the
    /// safe side).
    pub fn requests_stop(&self) -> bool {
        !matches!(self.action.get(), Ok(ViolationAction::Report))
    }

    /// True when `other` reports the same finding: the same rule, arm and violation time. The
    /// monitor sends an unanswered stop request again ([`crate::catalogue::SAFETY_VIOLATION`]
    /// readers see the copies); readers that count violations count one.
    pub fn same_finding(&self, other: &SafetyViolation) -> bool {
        self.violated_ns == other.violated_ns
            && self.rule == other.rule
            && self.arm_id == other.arm_id
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unknown_action_code_requests_the_stop() {
        let mut violation = SafetyViolation::default();
        assert!(!violation.requests_stop());
        violation.action.set(ViolationAction::Stop);
        assert!(violation.requests_stop());
        violation.action = WireCode::from_raw(77);
        assert!(violation.requests_stop());
    }

    #[test]
    fn a_resent_request_is_the_same_finding_and_another_time_is_not() {
        let first = SafetyViolation {
            violated_ns: 5,
            rule: ViolationRule::MovedDuringEmergencyStop.into(),
            arm_id: 2,
            ..SafetyViolation::default()
        };
        let mut resent = first;
        resent.header.msg_seq = 9;
        assert!(first.same_finding(&resent));
        let mut later = first;
        later.violated_ns = 6;
        assert!(!first.same_finding(&later));
        let mut other_arm = first;
        other_arm.arm_id = 1;
        assert!(!first.same_finding(&other_arm));
    }
}
