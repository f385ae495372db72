//! Which of the two tube arms sharing the centralized vacuum source (paper 003, section 2.3).
//!
//! Arm 1 is served by valves 1 (to the source) and 2 (to the atmosphere), arm 2 by valves 3 and 4
//! (Fig. 3). Everything in this crate speaks of an arm's *source valve*: "open" means the arm's
//! tube is connected to the vacuum source and closed to the atmosphere (valve 1 or 3 open, valve
//! 2 or 4 closed); "closed" means the reverse, which vents the tube and releases any apple.

use serde::{Deserialize, Serialize};
use std::fmt;

/// One of the two arms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ArmId {
    /// Arm 1 (valves 1 and 2, pressure sensor inside arm 1).
    Arm1,
    /// Arm 2 (valves 3 and 4, pressure sensor inside arm 2).
    Arm2,
}

impl ArmId {
    /// Both arms, arm 1 first.
    pub const ALL: [ArmId; 2] = [ArmId::Arm1, ArmId::Arm2];

    /// Zero-based index for per-arm arrays (`[T; 2]`).
    pub const fn index(self) -> usize {
        match self {
            ArmId::Arm1 => 0,
            ArmId::Arm2 => 1,
        }
    }

    /// The other arm.
    pub const fn other(self) -> ArmId {
        match self {
            ArmId::Arm1 => ArmId::Arm2,
            ArmId::Arm2 => ArmId::Arm1,
        }
    }
}

impl fmt::Display for ArmId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ArmId::Arm1 => f.write_str("arm 1"),
            ArmId::Arm2 => f.write_str("arm 2"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn other_is_an_involution_and_indices_are_distinct() {
        for arm in ArmId::ALL {
            assert_eq!(arm.other().other(), arm);
            assert_ne!(arm.other().index(), arm.index());
            assert_eq!(ArmId::ALL[arm.index()], arm);
        }
    }
}
