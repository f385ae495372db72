//! The coordination policy's view of the arms: each arm's phase from its published state and
//! the node's tracking, and the pair status the policy decides on.

use super::arm_track::ArmTrack;
use super::{VacuumNode, VacuumNodeInput};
use crate::policy::{ArmStatus, PairStatus};
use harvest_ipc::payloads::{ArmPhase as PhaseCode, ArmState};
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;

/// The policy's view of an arm's phase from its published state. A missing or stopped arm is
/// treated as away from the drop-off (it may be anywhere).
fn policy_phase(state: Option<&ArmState>, track: &ArmTrack) -> CoordinationPhase {
    if track.dispatched.is_some() {
        return CoordinationPhase::Approaching;
    }
    // An unknown phase code is treated like a missing state.
    match state.and_then(|s| s.phase.get().ok()) {
        Some(PhaseCode::Idle) => CoordinationPhase::Ready,
        Some(PhaseCode::Approach) => CoordinationPhase::Approaching,
        Some(PhaseCode::AttachDetach) if track.valve_open => CoordinationPhase::Attaching,
        // Closed again after the valve was granted: the attempt is over, the arm returns.
        Some(PhaseCode::AttachDetach) if track.opened_in_cycle => CoordinationPhase::Retracting,
        Some(PhaseCode::AttachDetach) => CoordinationPhase::AtApple,
        Some(PhaseCode::Retract) => CoordinationPhase::Retracting,
        Some(PhaseCode::Release) => CoordinationPhase::Releasing,
        Some(PhaseCode::Stopped) | None => CoordinationPhase::Approaching,
    }
}

impl VacuumNode {
    pub(super) fn pair(&self, input: &VacuumNodeInput<'_>) -> PairStatus {
        PairStatus(ArmId::ALL.map(|arm| {
            let i = arm.index();
            let track = &self.arms[i];
            ArmStatus {
                phase: policy_phase(input.arm_states[i], track),
                valve_open: track.valve_open,
                attachment: self.inference.state(arm),
                apple_assigned: self.config.arms_enabled[i]
                    && (track.dispatched.is_some() || !self.planner.queue(arm).is_empty()),
            }
        }))
    }
}
