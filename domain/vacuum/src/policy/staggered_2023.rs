//! The 2023 dual-arm policy (Lammers et al. 2024, as summarized in [dual-arm sec. 4.2]).
//!
//! No pressure feedback: the policy ignores the inferred attachment state. Both arms may
//! approach at the same time, but the vacuum is exclusive from the moment one arm opens its
//! valve (attach) through its retraction to the end of its release; only then may the other
//! arm open. A failed attachment is not noticed: the valve stays open until the release at the
//! drop-off, and the other arm waits for it.

use super::{
    Decision, PairStatus, PolicyKind, RefuseReason, Request, VacuumPolicy, ValveOrder,
    own_preconditions, workflow_close,
};
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;

/// The 2023 staggered policy.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Staggered2023;

impl VacuumPolicy for Staggered2023 {
    fn kind(&self) -> PolicyKind {
        PolicyKind::V2023
    }

    fn decide(&self, arm: ArmId, request: Request, arms: &PairStatus) -> Decision {
        if let Err(reason) = own_preconditions(arms.arm(arm), request) {
            return Decision::Refuse(reason);
        }
        match request {
            Request::StartApproach => Decision::Grant,
            Request::OpenValve => {
                let other = arms.arm(arm.other());
                let holds_vacuum = other.valve_open
                    || matches!(
                        other.phase,
                        CoordinationPhase::Attaching
                            | CoordinationPhase::Retracting
                            | CoordinationPhase::Releasing
                    );
                if holds_vacuum {
                    Decision::Refuse(RefuseReason::VacuumHeldByOther {
                        other_phase: other.phase,
                    })
                } else {
                    Decision::Grant
                }
            }
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
    fn vacuum_is_exclusive_until_the_other_release_is_done() {
        let p = Staggered2023;
        let waiting = ArmStatus {
            phase: CoordinationPhase::AtApple,
            valve_open: false,
            attachment: AttachmentState::Closed,
            apple_assigned: true,
        };
        for (phase, valve_open, granted) in [
            (CoordinationPhase::Approaching, false, true),
            (CoordinationPhase::AtApple, false, true),
            (CoordinationPhase::Attaching, true, false),
            (CoordinationPhase::Retracting, true, false),
            // Valve already closed for the release, apple still falling: still exclusive.
            (CoordinationPhase::Releasing, false, false),
            (CoordinationPhase::Ready, false, true),
        ] {
            let other = ArmStatus {
                phase,
                valve_open,
                attachment: if valve_open {
                    AttachmentState::Sealed
                } else {
                    AttachmentState::Closed
                },
                apple_assigned: true,
            };
            let d = p.decide(
                ArmId::Arm1,
                Request::OpenValve,
                &PairStatus([waiting, other]),
            );
            assert_eq!(d == Decision::Grant, granted, "other {phase}");
        }
    }

    #[test]
    fn ignores_pressure_failures_until_the_drop_off() {
        let p = Staggered2023;
        let failed = ArmStatus {
            phase: CoordinationPhase::Retracting,
            valve_open: true,
            attachment: AttachmentState::AttachFailed,
            apple_assigned: false,
        };
        let orders = p.supervise(&PairStatus([failed, ArmStatus::ready(false)]));
        assert_eq!(orders, [ValveOrder::Keep, ValveOrder::Keep]);
    }
}
