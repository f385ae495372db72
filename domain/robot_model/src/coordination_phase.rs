//! The phase of one arm as the vacuum coordination reasons about it ([dual-arm sec. 3.3]: each
//! cycle is split into Approach, Detach, Retract and Release; Fig. 9a), with the propositions
//! `Approach_i` (at the apple) and `Retract_i` (at the drop-off) of its logic.
//!
//! Three phase types, three concepts:
//! - [`CoordinationPhase`] (here): what the vacuum policies, the safety monitor's trace and the
//!   cycle model reason about. It splits "at the apple" into waiting for the vacuum
//!   ([`CoordinationPhase::AtApple`]) and attaching with the valve granted
//!   ([`CoordinationPhase::Attaching`]), which no arm reports: the vacuum supervisor knows it
//!   from its own valve bookkeeping.
//! - `harvest_ipc::payloads::ArmPhase`: the phase an arm reports in `ArmState::phase` on the wire
//!   (idle, the four cycle phases, stopped by the emergency stop).
//! - `harvest_arm::picking_cycle::CyclePhase`: the picking cycle state machine's own phases (the
//!   wire phases without "stopped", which is the arm node's state, not the cycle's).
//!
//! From the reported phase alone, [`CoordinationPhase::from_reported`] is the one mapping (the
//! safety monitor's view, live and in the evaluation). The vacuum supervisor refines it with what
//! it knows of the arm's valve (`policy_phase` in `harvest_vacuum::node`).

use harvest_ipc::payloads::ArmPhase as ReportedPhase;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Where one arm is in its picking cycle, as the vacuum coordination sees it (see the module
/// documentation for how it differs from the reported `ArmPhase` and the cycle's `CyclePhase`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CoordinationPhase {
    /// At the drop-off position with nothing to release: ready to start the next cycle
    /// (`Retract_i` holds, valve closed).
    Ready,
    /// Moving from the drop-off towards the assigned apple (between `Retract_i` and
    /// `Approach_i`).
    Approaching,
    /// At the apple with the valve still closed: waiting for the vacuum (`Approach_i` holds).
    AtApple,
    /// At the apple in the attach window: the valve has been granted and the arm performs the
    /// suction and the detach rotation (the "Detach" phase of the paper).
    Attaching,
    /// Moving back to the drop-off, with or without an apple.
    Retracting,
    /// At the drop-off releasing an apple: the valve must be (or is being) closed so the tube
    /// vents and the apple falls on the ramp (`Retract_i` holds).
    Releasing,
}

impl CoordinationPhase {
    /// The coordination phase of an arm that reports `reported` in `ArmState::phase`, from that
    /// phase alone: idle and stopped count as ready (at rest, valve closed; a stopped arm is
    /// braked wherever it is, which this view does not tell apart), attach/detach as attaching
    /// (an observer of the arm's state cannot tell waiting for the vacuum from attaching).
    pub const fn from_reported(reported: ReportedPhase) -> Self {
        match reported {
            ReportedPhase::Idle | ReportedPhase::Stopped => CoordinationPhase::Ready,
            ReportedPhase::Approach => CoordinationPhase::Approaching,
            ReportedPhase::AttachDetach => CoordinationPhase::Attaching,
            ReportedPhase::Retract => CoordinationPhase::Retracting,
            ReportedPhase::Release => CoordinationPhase::Releasing,
        }
    }

    /// True where the arm is at the drop-off position (the `Retract_i` proposition).
    pub const fn at_drop_off(self) -> bool {
        matches!(
            self,
            CoordinationPhase::Ready | CoordinationPhase::Releasing
        )
    }

    /// True where the arm is at its apple (the `Approach_i` proposition).
    pub const fn at_apple(self) -> bool {
        matches!(
            self,
            CoordinationPhase::AtApple | CoordinationPhase::Attaching
        )
    }
}

impl fmt::Display for CoordinationPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            CoordinationPhase::Ready => "ready",
            CoordinationPhase::Approaching => "approaching",
            CoordinationPhase::AtApple => "at apple",
            CoordinationPhase::Attaching => "attaching",
            CoordinationPhase::Retracting => "retracting",
            CoordinationPhase::Releasing => "releasing",
        };
        f.write_str(name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reported_phases_keep_the_coordination_propositions() {
        for reported in [ReportedPhase::Idle, ReportedPhase::Release] {
            let phase = CoordinationPhase::from_reported(reported);
            assert!(phase.at_drop_off() && !phase.at_apple(), "{reported:?}");
        }
        let at_apple = CoordinationPhase::from_reported(ReportedPhase::AttachDetach);
        assert!(at_apple.at_apple() && !at_apple.at_drop_off());
        for moving in [ReportedPhase::Approach, ReportedPhase::Retract] {
            let phase = CoordinationPhase::from_reported(moving);
            assert!(!phase.at_apple() && !phase.at_drop_off(), "{moving:?}");
        }
        // A stopped arm holds no valve open: the observer treats it as at rest.
        assert_eq!(
            CoordinationPhase::from_reported(ReportedPhase::Stopped),
            CoordinationPhase::Ready
        );
    }
}
