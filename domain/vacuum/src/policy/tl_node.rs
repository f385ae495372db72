//! The per-arm automaton of the 2024 policy: the nodes of Fig. 9a, derived from the atomic
//! propositions of eq. 7-12, and the transition relation the formulas allow.
//!
//! Atomic propositions of arm `i`, read off an [`ArmStatus`] ([`Propositions::of`]):
//! `Retract_i` (at the drop-off), `Approach_i` (at the apple), `Open_Valve_i` (source valve
//! open), `Apple_Attached_i` (valve open and cup sealed, eq. 10 makes attached imply open),
//! `Apple_Detected_i` (an apple is assigned). Each node is one satisfying assignment of these
//! propositions, split where the phase tells apart two situations the propositions alone do
//! not (moving out vs. moving back empty). The mapping formula -> node / transition is tabled
//! in POLICY.md.

use super::ArmStatus;
use crate::pressure::AttachmentState;
use harvest_robot_model::coordination_phase::CoordinationPhase;
use std::fmt;

/// The atomic propositions of eq. 7-12 for one arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Propositions {
    /// `Retract_i`: the arm is at its drop-off position.
    pub retract: bool,
    /// `Approach_i`: the arm has completed its approach and is at the apple.
    pub approach: bool,
    /// `Open_Valve_i`: the source valve is open.
    pub open_valve: bool,
    /// `Apple_Attached_i`: an apple is attached, as inferred from the pressure sensors.
    pub attached: bool,
    /// `Apple_Detected_i`: an apple is detected and assigned to the arm.
    pub detected: bool,
}

impl Propositions {
    /// The propositions of one arm's status. `attached` requires the valve open (eq. 10).
    pub const fn of(status: &ArmStatus) -> Self {
        Propositions {
            retract: status.phase.at_drop_off(),
            approach: status.phase.at_apple(),
            open_valve: status.valve_open,
            attached: status.sealed(),
            detected: status.apple_assigned,
        }
    }
}

/// A node of the per-arm automaton (Fig. 9a), with the propositions that define it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TlNode {
    /// `Retract ∧ ¬Open_Valve`: at the drop-off, empty; may approach when `Apple_Detected`.
    Idle,
    /// `¬Retract ∧ ¬Approach ∧ ¬Open_Valve`, moving towards the apple.
    Approaching,
    /// `Approach ∧ ¬Open_Valve`: at the apple, waiting for the vacuum.
    AwaitingVacuum,
    /// `Approach ∧ Open_Valve ∧ ¬Apple_Attached`: attempting attachment. At most one arm may
    /// be here unless the other is attached (eq. 11, clauses 3-4).
    Attempting,
    /// `Approach ∧ Open_Valve ∧ Apple_Attached`: sealed, detach rotation. Satisfies the seal
    /// condition that lets the other arm open.
    Detaching,
    /// `¬Retract ∧ ¬Approach ∧ Open_Valve ∧ Apple_Attached`: carrying the apple back.
    CarryingApple,
    /// `¬Approach ∧ ¬Open_Valve`, moving back to the drop-off after a failure (Fig. 9a orange
    /// path; no release phase).
    ReturningEmpty,
    /// `Retract ∧ Open_Valve ∧ Apple_Attached`: the goal state of eq. 7; eq. 8 clause 4 forces
    /// `¬Open_Valve` next (release).
    AtDropOffWithApple,
    /// `Open_Valve ∧ ¬Apple_Attached` outside the attach window, or a latched failure: eq. 11
    /// clauses 1-2 force `¬Open_Valve` next.
    Failing,
    /// `Open_Valve` before the approach is complete: forbidden by eq. 8 clause 2; never reached
    /// under the 2024 policy, closed at once if observed.
    Invalid,
}

impl TlNode {
    /// Every node.
    pub const ALL: [TlNode; 10] = [
        TlNode::Idle,
        TlNode::Approaching,
        TlNode::AwaitingVacuum,
        TlNode::Attempting,
        TlNode::Detaching,
        TlNode::CarryingApple,
        TlNode::ReturningEmpty,
        TlNode::AtDropOffWithApple,
        TlNode::Failing,
        TlNode::Invalid,
    ];

    /// The node an arm's status is in.
    pub const fn classify(status: &ArmStatus) -> TlNode {
        if !status.valve_open {
            return match status.phase {
                CoordinationPhase::Ready | CoordinationPhase::Releasing => TlNode::Idle,
                CoordinationPhase::Approaching => TlNode::Approaching,
                CoordinationPhase::AtApple => TlNode::AwaitingVacuum,
                CoordinationPhase::Attaching | CoordinationPhase::Retracting => {
                    TlNode::ReturningEmpty
                }
            };
        }
        if status.attachment.failure_kind().is_some() {
            return TlNode::Failing;
        }
        let sealed = matches!(status.attachment, AttachmentState::Sealed);
        match (status.phase, sealed) {
            (CoordinationPhase::Attaching, false) => TlNode::Attempting,
            (CoordinationPhase::Attaching, true) => TlNode::Detaching,
            (CoordinationPhase::Retracting, true) => TlNode::CarryingApple,
            (CoordinationPhase::Releasing, true) => TlNode::AtDropOffWithApple,
            (CoordinationPhase::Retracting | CoordinationPhase::Releasing, false) => {
                TlNode::Failing
            }
            (
                CoordinationPhase::Ready
                | CoordinationPhase::Approaching
                | CoordinationPhase::AtApple,
                _,
            ) => TlNode::Invalid,
        }
    }

    /// The nodes the 2024 policy lets this node move to in one step (self-loop included).
    /// Derived from eq. 8 (workflow order), eq. 10 (attached only when open) and eq. 11
    /// (failures close the valve); the arm-pair constraint (eq. 11 clauses 3-4) is a guard on
    /// `AwaitingVacuum -> Attempting`, see [`super::FailureAware2024`].
    pub const fn successors(self) -> &'static [TlNode] {
        use TlNode::*;
        match self {
            Idle => &[Idle, Approaching],
            Approaching => &[Approaching, AwaitingVacuum],
            AwaitingVacuum => &[AwaitingVacuum, Attempting],
            Attempting => &[Attempting, Detaching, Failing, ReturningEmpty],
            Detaching => &[Detaching, CarryingApple, Failing],
            CarryingApple => &[CarryingApple, AtDropOffWithApple, Failing],
            AtDropOffWithApple => &[AtDropOffWithApple, Idle],
            Failing => &[Failing, ReturningEmpty, Idle],
            ReturningEmpty => &[ReturningEmpty, Idle],
            Invalid => &[Invalid, Idle, Approaching, AwaitingVacuum, ReturningEmpty],
        }
    }

    /// True if `next` may follow `self` in one step.
    pub fn may_precede(self, next: TlNode) -> bool {
        self.successors().contains(&next)
    }

    /// True where the valve must be closed in the next step (eq. 8 clause 4, eq. 11 clauses
    /// 1-2, eq. 8 clause 2 for `Invalid`).
    pub const fn must_close(self) -> bool {
        matches!(
            self,
            TlNode::AtDropOffWithApple | TlNode::Failing | TlNode::Invalid
        )
    }

    /// True where this arm's valve is open without a seal: while the other arm is here it may
    /// not open its own valve (eq. 11 clauses 3-4).
    pub const fn blocks_other_attempt(self) -> bool {
        matches!(self, TlNode::Attempting | TlNode::Failing | TlNode::Invalid)
    }
}

impl fmt::Display for TlNode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PHASES: [CoordinationPhase; 6] = [
        CoordinationPhase::Ready,
        CoordinationPhase::Approaching,
        CoordinationPhase::AtApple,
        CoordinationPhase::Attaching,
        CoordinationPhase::Retracting,
        CoordinationPhase::Releasing,
    ];
    const ATTACHMENTS: [AttachmentState; 5] = [
        AttachmentState::Closed,
        AttachmentState::OpenToAtmosphere,
        AttachmentState::Sealed,
        AttachmentState::AttachFailed,
        AttachmentState::Dropped,
    ];

    fn all_statuses() -> Vec<ArmStatus> {
        let mut out = Vec::new();
        for phase in PHASES {
            for valve_open in [false, true] {
                for attachment in ATTACHMENTS {
                    for apple_assigned in [false, true] {
                        out.push(ArmStatus {
                            phase,
                            valve_open,
                            attachment,
                            apple_assigned,
                        });
                    }
                }
            }
        }
        out
    }

    /// Each node's defining propositions hold for every status classified into it.
    #[test]
    fn every_status_lands_in_the_node_its_propositions_define() {
        for s in all_statuses() {
            let p = Propositions::of(&s);
            // eq. 10: attached implies open, by construction.
            assert!(!p.attached || p.open_valve);
            let node = TlNode::classify(&s);
            let ok = match node {
                TlNode::Idle => p.retract && !p.open_valve,
                TlNode::Approaching => !p.retract && !p.approach && !p.open_valve,
                TlNode::AwaitingVacuum => p.approach && !p.open_valve,
                TlNode::Attempting => p.approach && p.open_valve && !p.attached,
                TlNode::Detaching => p.approach && p.open_valve && p.attached,
                TlNode::CarryingApple => !p.retract && !p.approach && p.open_valve && p.attached,
                TlNode::ReturningEmpty => !p.retract && !p.open_valve,
                TlNode::AtDropOffWithApple => p.retract && p.open_valve && p.attached,
                TlNode::Failing => {
                    p.open_valve && (!p.attached || s.attachment.failure_kind().is_some())
                }
                TlNode::Invalid => {
                    p.open_valve
                        && matches!(
                            s.phase,
                            CoordinationPhase::Ready
                                | CoordinationPhase::Approaching
                                | CoordinationPhase::AtApple
                        )
                }
            };
            assert!(ok, "{s:?} classified {node} with {p:?}");
        }
    }

    #[test]
    fn every_node_is_reachable_by_some_status_and_relation_is_closed() {
        let statuses = all_statuses();
        for node in TlNode::ALL {
            assert!(
                statuses.iter().any(|s| TlNode::classify(s) == node),
                "{node} unreachable"
            );
            assert!(node.may_precede(node), "{node} lacks its self-loop");
            // A node that must close never moves to a node that keeps the valve open, except
            // staying put for the one control period the close takes.
            if node.must_close() {
                for &next in node.successors() {
                    assert!(
                        next == node
                            || !matches!(
                                next,
                                TlNode::Attempting | TlNode::Detaching | TlNode::CarryingApple
                            )
                    );
                }
            }
        }
        // The goal (eq. 7) is reachable from Idle along the relation.
        let mut seen = vec![TlNode::Idle];
        let mut i = 0;
        while i < seen.len() {
            for &n in seen[i].successors() {
                if !seen.contains(&n) {
                    seen.push(n);
                }
            }
            i += 1;
        }
        assert!(seen.contains(&TlNode::AtDropOffWithApple));
        assert!(!seen.contains(&TlNode::Invalid));
    }

    #[test]
    fn a_sealed_valve_is_never_closed_before_the_drop_off() {
        for sealed in [TlNode::Detaching, TlNode::CarryingApple] {
            assert!(!sealed.may_precede(TlNode::ReturningEmpty));
            assert!(!sealed.may_precede(TlNode::Idle));
        }
    }
}
