//! The no-coordination baseline of [dual-arm sec. 4.2, Fig. 12]: the two arms work
//! strictly one after the other. An arm may leave the drop-off only while the other one rests
//! there with its valve closed; the valve itself is then never contended and is granted
//! without looking at the other arm or at the pressures. Failures are not detected: a valve
//! closes only for the release at the drop-off.

use super::{
    Decision, PairStatus, PolicyKind, RefuseReason, Request, VacuumPolicy, ValveOrder,
    own_preconditions, workflow_close,
};
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;

/// The sequential, uncoordinated baseline.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SequentialBaseline;

impl VacuumPolicy for SequentialBaseline {
    fn kind(&self) -> PolicyKind {
        PolicyKind::Baseline
    }

    fn decide(&self, arm: ArmId, request: Request, arms: &PairStatus) -> Decision {
        if let Err(reason) = own_preconditions(arms.arm(arm), request) {
            return Decision::Refuse(reason);
        }
        match request {
            Request::StartApproach => {
                let other = arms.arm(arm.other());
                if other.phase == CoordinationPhase::Ready && !other.valve_open {
                    Decision::Grant
                } else {
                    Decision::Refuse(RefuseReason::OtherArmActive {
                        other_phase: other.phase,
                    })
                }
            }
            Request::OpenValve => Decision::Grant,
        }
    }

    fn supervise(&self, arms: &PairStatus) -> [ValveOrder; 2] {
        ArmId::ALL.map(|arm| workflow_close(arms.arm(arm)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::ArmStatus;
    use crate::pressure::AttachmentState;

    #[test]
    fn one_arm_at_a_time() {
        let p = SequentialBaseline;
        let ready = ArmStatus::ready(true);
        assert_eq!(
            p.decide(
                ArmId::Arm2,
                Request::StartApproach,
                &PairStatus([ready, ready])
            ),
            Decision::Grant
        );
        for phase in [
            CoordinationPhase::Approaching,
            CoordinationPhase::AtApple,
            CoordinationPhase::Attaching,
            CoordinationPhase::Retracting,
            CoordinationPhase::Releasing,
        ] {
            let busy = ArmStatus {
                phase,
                valve_open: false,
                attachment: AttachmentState::Closed,
                apple_assigned: true,
            };
            assert_eq!(
                p.decide(
                    ArmId::Arm2,
                    Request::StartApproach,
                    &PairStatus([busy, ready])
                ),
                Decision::Refuse(RefuseReason::OtherArmActive { other_phase: phase })
            );
        }
    }
}
