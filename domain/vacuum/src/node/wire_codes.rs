//! The numbers the node puts on the wire: refusal codes of `ValveGrant::reason`, the policy
//! and attachment codes of `VacuumState`, and the apple id of `ArmTarget` / `ArmState`.

use crate::assignment::AppleId;
use crate::policy::{PolicyKind, RefuseReason};
use crate::pressure::AttachmentState;

/// Refusal code sent in `ValveGrant::reason` while the emergency stop is engaged.
pub const REFUSED_EMERGENCY_STOP: u8 = 20;
/// Refusal code for an arm that does not take part (single-arm operation).
pub const REFUSED_ARM_DISABLED: u8 = 21;

/// The wire code of a policy refusal (`ValveGrant::reason`; 0 = none).
pub fn refuse_reason_code(reason: &RefuseReason) -> u8 {
    match reason {
        RefuseReason::NotReady { .. } => 1,
        RefuseReason::NoAppleAssigned => 2,
        RefuseReason::NotAtApple { .. } => 3,
        RefuseReason::ValveAlreadyOpen => 4,
        RefuseReason::OtherArmAttempting => 5,
        RefuseReason::OtherArmFailing => 6,
        RefuseReason::VacuumHeldByOther { .. } => 7,
        RefuseReason::OtherArmActive { .. } => 8,
    }
}

/// The policy code of `VacuumState::policy` (0 baseline, 1 2023, 2 2024).
pub fn policy_code(kind: PolicyKind) -> u8 {
    match kind {
        PolicyKind::Baseline => 0,
        PolicyKind::V2023 => 1,
        PolicyKind::V2024 => 2,
    }
}

/// The attachment code of `VacuumState::arm_attachment` (0 closed, 1 open, 2 sealed; a latched
/// failure is open and unsealed).
pub fn attachment_code(state: AttachmentState) -> u8 {
    match state {
        AttachmentState::Closed => 0,
        AttachmentState::Sealed => 2,
        AttachmentState::OpenToAtmosphere
        | AttachmentState::AttachFailed
        | AttachmentState::Dropped => 1,
    }
}

/// The apple id on the wire (`ArmTarget::apple_id`, `ArmState::apple_id`): the planner's id
/// plus one, so that 0 keeps meaning "no apple".
pub fn wire_id(id: AppleId) -> u32 {
    id.0.wrapping_add(1)
}
