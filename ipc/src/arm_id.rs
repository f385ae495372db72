//! Which of the robot's two arms: the one arm identifier of the whole stack (channel selection in
//! the catalogue, the robot model's [dual-arm Table 1] parameters, the policies, the monitor, the simulator).

use serde::{Deserialize, Serialize};
use std::fmt;

/// Arm 1 or arm 2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum ArmId {
    /// Arm 1, mounted on the +y (left) side.
    Arm1,
    /// Arm 2, mounted on the -y (right) side.
    Arm2,
}

impl ArmId {
    /// Both arms, in index order.
    pub const ALL: [ArmId; 2] = [ArmId::Arm1, ArmId::Arm2];

    /// The arm numbered 1 or 2 (command lines, wire ids); `None` for any other number.
    pub const fn from_number(number: u8) -> Option<Self> {
        match number {
            1 => Some(Self::Arm1),
            2 => Some(Self::Arm2),
            _ => None,
        }
    }

    /// 1 or 2.
    pub const fn number(self) -> u8 {
        match self {
            Self::Arm1 => 1,
            Self::Arm2 => 2,
        }
    }

    /// 0 or 1: the arm's slot in per-arm arrays.
    pub const fn index(self) -> usize {
        self.number() as usize - 1
    }

    /// The arm on the other side.
    pub const fn other(self) -> Self {
        match self {
            Self::Arm1 => Self::Arm2,
            Self::Arm2 => Self::Arm1,
        }
    }
}

impl fmt::Display for ArmId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "arm {}", self.number())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_indices_and_others_agree() {
        for arm in ArmId::ALL {
            assert_eq!(ArmId::from_number(arm.number()), Some(arm));
            assert_eq!(ArmId::ALL[arm.index()], arm);
            assert_ne!(arm.other(), arm);
        }
        assert_eq!(ArmId::from_number(3), None);
        assert_eq!(ArmId::Arm2.to_string(), "arm 2");
    }
}
