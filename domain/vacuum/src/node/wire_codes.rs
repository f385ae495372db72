//! The numbers the node puts on the wire: refusal codes of `ValveGrant::reason`, the policy
//! and attachment codes of `VacuumState`, and the apple id of `ArmTarget` / `ArmState`.

use crate::assignment::AppleId;
use crate::policy::{PolicyKind, RefuseReason};
use crate::pressure::AttachmentState;
use harvest_ipc::payloads::{ArmAttachment, VacuumPolicyCode};

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

/// The policy as published in `VacuumState::policy`.
pub fn policy_code(kind: PolicyKind) -> VacuumPolicyCode {
    match kind {
        PolicyKind::Baseline => VacuumPolicyCode::Baseline,
        PolicyKind::V2023 => VacuumPolicyCode::Policy2023,
        PolicyKind::V2024 => VacuumPolicyCode::Policy2024,
    }
}

/// The attachment as published in `VacuumState::arm_attachment` (a latched failure is open and
/// unsealed).
pub fn attachment_code(state: AttachmentState) -> ArmAttachment {
    match state {
        AttachmentState::Closed => ArmAttachment::Closed,
        AttachmentState::Sealed => ArmAttachment::Sealed,
        AttachmentState::OpenToAtmosphere
        | AttachmentState::AttachFailed
        | AttachmentState::Dropped => ArmAttachment::Open,
    }
}

/// The apple id on the wire (`ArmTarget::apple_id`, `ArmState::apple_id`): the planner's id
/// plus one, so that 0 keeps meaning "no apple".
pub fn wire_id(id: AppleId) -> u32 {
    id.0.wrapping_add(1)
}
