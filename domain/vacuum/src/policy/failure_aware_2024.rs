//! The 2024 failure-aware coordination policy ([dual-arm sec. 3.3, eq. 7-12]), run as the
//! explicit automaton of [`TlNode`].
//!
//! Guards and orders, each traced to its clause (full table in POLICY.md):
//! - `StartApproach` needs `Retract_i ∧ Apple_Detected_i` (eq. 8 clause 1).
//! - `OpenValve` needs `Approach_i` (eq. 8 clause 2) and is refused while the other arm is
//!   `Open_Valve ∧ ¬Apple_Attached` (eq. 11 clauses 3-4): at most one arm attempts attachment
//!   at a time unless the other's apple is sealed.
//! - A valve is force-closed at once on a failed attachment or a drop (eq. 11 clauses 1-2), at
//!   the end of an attach window without a seal (eq. 8 clause 3 with eq. 11 clauses 1-2), and at
//!   the drop-off with an apple, which releases it (eq. 8 clause 4).
//!
//! Eq. 7 (the goal) is what these guards keep reachable; eq. 10 holds by construction of
//! `Apple_Attached` (sealed implies open).

use super::{
    ArmStatus, CloseReason, Decision, PairStatus, PolicyKind, RefuseReason, Request, TlNode,
    VacuumPolicy, ValveOrder, own_preconditions,
};
use crate::pressure::AttachmentState;
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;

/// The failure-aware temporal-logic policy of eq. 7-12.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FailureAware2024;

impl FailureAware2024 {
    /// Why a node that must close does so.
    fn close_reason(status: &ArmStatus, node: TlNode) -> CloseReason {
        match (node, status.attachment) {
            (TlNode::AtDropOffWithApple, _) => CloseReason::Release,
            (TlNode::Invalid, _) => CloseReason::OutOfWorkflow {
                phase: status.phase,
            },
            (_, AttachmentState::AttachFailed) => CloseReason::AttachFailed,
            (_, AttachmentState::Dropped) => CloseReason::Dropped,
            _ if status.phase == CoordinationPhase::Releasing => CloseReason::Release,
            _ => CloseReason::NoSealAtRetract,
        }
    }
}

impl VacuumPolicy for FailureAware2024 {
    fn kind(&self) -> PolicyKind {
        PolicyKind::V2024
    }

    fn decide(&self, arm: ArmId, request: Request, arms: &PairStatus) -> Decision {
        if let Err(reason) = own_preconditions(arms.arm(arm), request) {
            return Decision::Refuse(reason);
        }
        match request {
            Request::StartApproach => Decision::Grant,
            Request::OpenValve => match TlNode::classify(arms.arm(arm.other())) {
                TlNode::Attempting => Decision::Refuse(RefuseReason::OtherArmAttempting),
                other if other.blocks_other_attempt() => {
                    Decision::Refuse(RefuseReason::OtherArmFailing)
                }
                _ => Decision::Grant,
            },
        }
    }

    fn supervise(&self, arms: &PairStatus) -> [ValveOrder; 2] {
        ArmId::ALL.map(|arm| {
            let status = arms.arm(arm);
            let node = TlNode::classify(status);
            if node.must_close() {
                ValveOrder::ForceClose(Self::close_reason(status, node))
            } else {
                ValveOrder::Keep
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(
        phase: CoordinationPhase,
        valve_open: bool,
        attachment: AttachmentState,
    ) -> ArmStatus {
        ArmStatus {
            phase,
            valve_open,
            attachment,
            apple_assigned: true,
        }
    }

    const WAITING: ArmStatus = ArmStatus {
        phase: CoordinationPhase::AtApple,
        valve_open: false,
        attachment: AttachmentState::Closed,
        apple_assigned: true,
    };

    #[test]
    fn second_arm_waits_while_the_first_attempts_and_goes_once_it_seals() {
        let p = FailureAware2024;
        let attempting = status(
            CoordinationPhase::Attaching,
            true,
            AttachmentState::OpenToAtmosphere,
        );
        let pair = PairStatus([attempting, WAITING]);
        assert_eq!(
            p.decide(ArmId::Arm2, Request::OpenValve, &pair),
            Decision::Refuse(RefuseReason::OtherArmAttempting)
        );
        // Just granted, inference not yet updated (attachment still Closed): still attempting.
        let just_opened = status(CoordinationPhase::Attaching, true, AttachmentState::Closed);
        assert_eq!(
            p.decide(
                ArmId::Arm2,
                Request::OpenValve,
                &PairStatus([just_opened, WAITING])
            ),
            Decision::Refuse(RefuseReason::OtherArmAttempting)
        );
        for sealed_phase in [
            CoordinationPhase::Attaching,
            CoordinationPhase::Retracting,
            CoordinationPhase::Releasing,
        ] {
            let sealed = status(sealed_phase, true, AttachmentState::Sealed);
            assert_eq!(
                p.decide(
                    ArmId::Arm2,
                    Request::OpenValve,
                    &PairStatus([sealed, WAITING])
                ),
                Decision::Grant,
                "other arm sealed while {sealed_phase}"
            );
        }
        // Other arm's valve closed after a failure, still moving: free.
        let returning = status(
            CoordinationPhase::Retracting,
            false,
            AttachmentState::Closed,
        );
        assert_eq!(
            p.decide(
                ArmId::Arm2,
                Request::OpenValve,
                &PairStatus([returning, WAITING])
            ),
            Decision::Grant
        );
    }

    #[test]
    fn failures_close_at_once_and_a_sealed_carry_is_kept() {
        let p = FailureAware2024;
        let cases = [
            (
                status(
                    CoordinationPhase::Attaching,
                    true,
                    AttachmentState::AttachFailed,
                ),
                ValveOrder::ForceClose(CloseReason::AttachFailed),
            ),
            (
                status(
                    CoordinationPhase::Retracting,
                    true,
                    AttachmentState::Dropped,
                ),
                ValveOrder::ForceClose(CloseReason::Dropped),
            ),
            (
                status(CoordinationPhase::Attaching, true, AttachmentState::Dropped),
                ValveOrder::ForceClose(CloseReason::Dropped),
            ),
            (
                status(
                    CoordinationPhase::Retracting,
                    true,
                    AttachmentState::OpenToAtmosphere,
                ),
                ValveOrder::ForceClose(CloseReason::NoSealAtRetract),
            ),
            (
                status(CoordinationPhase::Releasing, true, AttachmentState::Sealed),
                ValveOrder::ForceClose(CloseReason::Release),
            ),
            (
                status(
                    CoordinationPhase::AtApple,
                    true,
                    AttachmentState::OpenToAtmosphere,
                ),
                ValveOrder::ForceClose(CloseReason::OutOfWorkflow {
                    phase: CoordinationPhase::AtApple,
                }),
            ),
            (
                status(CoordinationPhase::Retracting, true, AttachmentState::Sealed),
                ValveOrder::Keep,
            ),
            (
                status(
                    CoordinationPhase::Attaching,
                    true,
                    AttachmentState::OpenToAtmosphere,
                ),
                ValveOrder::Keep,
            ),
        ];
        for (s, expected) in cases {
            let orders = p.supervise(&PairStatus([s, ArmStatus::ready(false)]));
            assert_eq!(orders, [expected, ValveOrder::Keep], "{s:?}");
        }
    }

    #[test]
    fn never_grants_an_attempt_next_to_an_unsealed_open_valve() {
        // Exhaustive over the other arm's status: a grant implies the other arm is closed or
        // sealed (the key property of eq. 11 clauses 3-4).
        let phases = [
            CoordinationPhase::Ready,
            CoordinationPhase::Approaching,
            CoordinationPhase::AtApple,
            CoordinationPhase::Attaching,
            CoordinationPhase::Retracting,
            CoordinationPhase::Releasing,
        ];
        let attachments = [
            AttachmentState::Closed,
            AttachmentState::OpenToAtmosphere,
            AttachmentState::Sealed,
            AttachmentState::AttachFailed,
            AttachmentState::Dropped,
        ];
        let p = FailureAware2024;
        for phase in phases {
            for valve_open in [false, true] {
                for attachment in attachments {
                    let other = status(phase, valve_open, attachment);
                    let d = p.decide(
                        ArmId::Arm1,
                        Request::OpenValve,
                        &PairStatus([WAITING, other]),
                    );
                    if d == Decision::Grant {
                        assert!(!other.valve_open || other.sealed(), "{other:?}");
                    }
                }
            }
        }
    }
}
