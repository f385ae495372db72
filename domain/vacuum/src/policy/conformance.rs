//! Conformance tests written once over [`VacuumPolicy`] and run for every implementation.

use super::*;
use crate::pressure::AttachmentState;

fn every_policy() -> Vec<Box<dyn VacuumPolicy + Send + Sync>> {
    PolicyKind::ALL.into_iter().map(new_policy).collect()
}

#[test]
fn kind_round_trips_through_the_factory() {
    for kind in PolicyKind::ALL {
        assert_eq!(new_policy(kind).kind(), kind);
    }
}

#[test]
fn own_workflow_preconditions_are_enforced_by_every_policy() {
    let ready_no_apple = ArmStatus::ready(false);
    let approaching = ArmStatus {
        phase: CoordinationPhase::Approaching,
        ..ArmStatus::ready(true)
    };
    let idle_other = ArmStatus::ready(false);
    for p in every_policy() {
        let k = p.kind();
        assert_eq!(
            p.decide(
                ArmId::Arm1,
                Request::StartApproach,
                &PairStatus([ready_no_apple, idle_other])
            ),
            Decision::Refuse(RefuseReason::NoAppleAssigned),
            "{k}"
        );
        assert_eq!(
            p.decide(
                ArmId::Arm1,
                Request::StartApproach,
                &PairStatus([approaching, idle_other])
            ),
            Decision::Refuse(RefuseReason::NotReady {
                phase: CoordinationPhase::Approaching
            }),
            "{k}"
        );
        assert_eq!(
            p.decide(
                ArmId::Arm1,
                Request::OpenValve,
                &PairStatus([approaching, idle_other])
            ),
            Decision::Refuse(RefuseReason::NotAtApple {
                phase: CoordinationPhase::Approaching
            }),
            "{k}"
        );
        // Both idle with apples: the first asker may go.
        let ready = ArmStatus::ready(true);
        assert_eq!(
            p.decide(
                ArmId::Arm2,
                Request::StartApproach,
                &PairStatus([ready, ready])
            ),
            Decision::Grant,
            "{k}"
        );
        let waiting = ArmStatus {
            phase: CoordinationPhase::AtApple,
            ..ready
        };
        assert_eq!(
            p.decide(
                ArmId::Arm1,
                Request::OpenValve,
                &PairStatus([waiting, idle_other])
            ),
            Decision::Grant,
            "{k}"
        );
    }
}

#[test]
fn every_policy_releases_at_the_drop_off_and_leaves_closed_valves_alone() {
    let at_drop_off = ArmStatus {
        phase: CoordinationPhase::Releasing,
        valve_open: true,
        attachment: AttachmentState::Sealed,
        apple_assigned: false,
    };
    let carrying = ArmStatus {
        phase: CoordinationPhase::Retracting,
        valve_open: true,
        attachment: AttachmentState::Sealed,
        apple_assigned: true,
    };
    for p in every_policy() {
        let k = p.kind();
        assert_eq!(
            p.supervise(&PairStatus([carrying, at_drop_off])),
            [
                ValveOrder::Keep,
                ValveOrder::ForceClose(CloseReason::Release)
            ],
            "{k}"
        );
        assert_eq!(
            p.supervise(&PairStatus([ArmStatus::ready(true); 2])),
            [ValveOrder::Keep; 2],
            "{k}"
        );
    }
}
