//! The workflow phase of one arm's picking cycle (paper 003, section 3.3: each cycle is split
//! into Approach, Detach, Retract and Release; Fig. 9a).
//!
//! The phase is reported by the arm's workflow executor (the arm process, or the cycle model);
//! the vacuum policies read it together with the valve state and the attachment state inferred
//! from the pressure sensors.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Where one arm is in its picking cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ArmPhase {
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

impl ArmPhase {
    /// True where the arm is at the drop-off position (the `Retract_i` proposition).
    pub const fn at_drop_off(self) -> bool {
        matches!(self, ArmPhase::Ready | ArmPhase::Releasing)
    }

    /// True where the arm is at its apple (the `Approach_i` proposition).
    pub const fn at_apple(self) -> bool {
        matches!(self, ArmPhase::AtApple | ArmPhase::Attaching)
    }
}

impl fmt::Display for ArmPhase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            ArmPhase::Ready => "ready",
            ArmPhase::Approaching => "approaching",
            ArmPhase::AtApple => "at apple",
            ArmPhase::Attaching => "attaching",
            ArmPhase::Retracting => "retracting",
            ArmPhase::Releasing => "releasing",
        };
        f.write_str(name)
    }
}
