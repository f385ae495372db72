//! A [`Violation`] as the `safety/violation` message the monitor publishes in the stack
//! (`--on-violation report|stop`), and what the monitor does about violations.

use harvest_ipc::FixedString;
use harvest_ipc::payloads::{SafetyViolation, ViolationAction, ViolationRule};
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::Violation;

/// What the live monitor does with a violation beyond printing it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnViolation {
    /// Print only; publish nothing (a monitor started by hand beside a stack).
    Print,
    /// Publish it on `safety/violation` (the recorder keeps it, `harvest up` names it).
    Report,
    /// Publish it and ask the executive for the protective stop.
    Stop,
}

impl OnViolation {
    /// The action carried by the message, `None` when nothing is published.
    pub fn action(self) -> Option<ViolationAction> {
        match self {
            Self::Print => None,
            Self::Report => Some(ViolationAction::Report),
            Self::Stop => Some(ViolationAction::Stop),
        }
    }
}

/// The rule, the arm (1 or 2; 0 for both or none) and when the rule was broken, ns.
pub fn classify(violation: &Violation) -> (ViolationRule, u8, u64) {
    let arm_code = |arm: ArmId| arm.index() as u8 + 1;
    match *violation {
        Violation::OpenedBesideUnsealed { stamp_ns, arm } => {
            (ViolationRule::OpenedBesideUnsealed, arm_code(arm), stamp_ns)
        }
        Violation::BothOpenUnsealed { noticed_ns, .. } => {
            (ViolationRule::BothOpenUnsealed, 0, noticed_ns)
        }
        Violation::FailureNotClosed {
            arm, deadline_ns, ..
        } => (ViolationRule::FailureNotClosed, arm_code(arm), deadline_ns),
        Violation::JointOutOfLimits { stamp_ns, arm, .. } => {
            (ViolationRule::JointOutOfLimits, arm_code(arm), stamp_ns)
        }
        Violation::ValveOpenDuringEmergencyStop { arm, stamp_ns, .. } => (
            ViolationRule::ValveOpenDuringEmergencyStop,
            arm_code(arm),
            stamp_ns,
        ),
        Violation::MovedDuringEmergencyStop { arm, stamp_ns, .. } => (
            ViolationRule::MovedDuringEmergencyStop,
            arm_code(arm),
            stamp_ns,
        ),
        Violation::EndEffectorsTooClose { stamp_ns, .. } => {
            (ViolationRule::EndEffectorsTooClose, 0, stamp_ns)
        }
    }
}

/// Fills `message` (header left to the publisher) for `violation` with `action`.
pub fn fill_message(message: &mut SafetyViolation, violation: &Violation, action: ViolationAction) {
    let (rule, arm_id, violated_ns) = classify(violation);
    message.violated_ns = violated_ns;
    message.rule.set(rule);
    message.action.set(action);
    message.arm_id = arm_id;
    message._reserved = [0; 5];
    message.description = FixedString::new(&violation.to_string());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_violation_becomes_its_rule_arm_and_words() {
        let violation = Violation::OpenedBesideUnsealed {
            stamp_ns: 7,
            arm: ArmId::Arm2,
        };
        let mut message = SafetyViolation::default();
        fill_message(&mut message, &violation, ViolationAction::Stop);
        assert_eq!(message.rule.get(), Ok(ViolationRule::OpenedBesideUnsealed));
        assert_eq!(message.arm_id, 2);
        assert_eq!(message.violated_ns, 7);
        assert!(message.requests_stop());
        assert_eq!(message.description.as_str(), violation.to_string());
    }
}
