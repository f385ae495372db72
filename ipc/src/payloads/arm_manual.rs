//! Manual motion orders to one arm (`armN/manual`), forwarded by the executive from an accepted
//! operator command (jog, drop-off, home). The arm process carries them out only in manual mode
//! (`operator/mode`), never during a picking cycle or an emergency stop.

use crate::header::Header;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// What the arm is told to do (code in [`ArmManualCommand::kind`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ArmManualKind {
    /// Move to `goal_joint_position` on a rest-to-rest trajectory.
    MoveTo = 1,
    /// Stop the manual motion where the arm is.
    Stop = 2,
}

impl ArmManualKind {
    /// The kind with this wire code; `None` for an unknown code.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(Self::MoveTo),
            2 => Some(Self::Stop),
            _ => None,
        }
    }
}

/// One manual order. `header.capture_ns` is when the executive decided it.
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
#[type_name("harvest.ArmManualCommand.v1")]
pub struct ArmManualCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The operator command's `request_id` behind this order.
    pub request_id: u64,
    /// The arm, 1 or 2.
    pub arm_id: u8,
    /// [`ArmManualKind`] code.
    pub kind: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 6],
    /// `[D m, theta rad, phi rad, twist rad]`, inside the arm's joint limits.
    pub goal_joint_position: [f64; 4],
    /// Fraction (0, 1] of the arm's rate limits the motion may use.
    pub speed_fraction: f64,
}

impl ArmManualCommand {
    /// The order's kind; `None` for an unknown code.
    pub fn manual_kind(&self) -> Option<ArmManualKind> {
        ArmManualKind::from_code(self.kind)
    }
}
