//! Vacuum coordination policies: who may open a source valve, and which valves must close now.
//!
//! The two arms share one vacuum source ([dual-arm sec. 2.3]). A policy sees a snapshot of
//! both arms ([`PairStatus`]: workflow phase, commanded valve state, attachment state inferred
//! from the pressure sensors, whether an apple is assigned) and
//! - answers an arm's request ([`VacuumPolicy::decide`]) with [`Decision::Grant`] or
//!   [`Decision::Refuse`] and a reason; a refused arm keeps waiting and asks again when the
//!   snapshot changes;
//! - orders valves closed at once ([`VacuumPolicy::supervise`], called every control period and
//!   after every change): [`ValveOrder::ForceClose`] with a reason.
//!
//! Contract for the caller: the snapshot must reflect every order and grant already given
//! (after granting `OpenValve` to one arm, that arm's valve is open in the next snapshot even if
//! the pressure has not moved yet), requests are decided one at a time, and a force-close is
//! applied within the same control period.
//!
//! Implementations, one per file (section 4.2 and Fig. 12 of the paper):
//! - [`FailureAware2024`]: the failure-aware temporal-logic policy of eq. 7-12 as an explicit
//!   state machine ([`TlNode`]);
//! - [`Staggered2023`]: the 2023 policy, no pressure feedback: the vacuum is exclusive from one
//!   arm's attach until its release is complete;
//! - [`SequentialBaseline`]: no coordination, the arms run strictly one after the other.
//!
//! The policy in use is chosen in one place: [`PolicyKind`] and [`new_policy`].

mod failure_aware_2024;
mod sequential_baseline;
mod staggered_2023;
mod tl_node;

pub use failure_aware_2024::FailureAware2024;
pub use sequential_baseline::SequentialBaseline;
pub use staggered_2023::Staggered2023;
pub use tl_node::{Propositions, TlNode};

use crate::pressure::AttachmentState;
use harvest_robot_model::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;
use serde::{Deserialize, Serialize};
use std::fmt;

/// What one arm looks like to a policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ArmStatus {
    /// Workflow phase reported by the arm.
    pub phase: CoordinationPhase,
    /// Commanded state of the arm's source valve (`Open_Valve_i`).
    pub valve_open: bool,
    /// State inferred from the pressure sensors (`Apple_Attached_i` is `Sealed`).
    pub attachment: AttachmentState,
    /// An apple is assigned to this arm and not yet attempted (`Apple_Detected_i`).
    pub apple_assigned: bool,
}

impl ArmStatus {
    /// An arm at its drop-off, valve closed, with or without an apple waiting.
    pub const fn ready(apple_assigned: bool) -> Self {
        ArmStatus {
            phase: CoordinationPhase::Ready,
            valve_open: false,
            attachment: AttachmentState::Closed,
            apple_assigned,
        }
    }

    /// `Apple_Attached_i`: the valve is open and the cup is sealed.
    pub const fn sealed(&self) -> bool {
        self.valve_open && self.attachment.is_sealed()
    }
}

/// Both arms, indexed by [`ArmId::index`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct PairStatus(pub [ArmStatus; 2]);

impl PairStatus {
    /// The status of `arm`.
    pub const fn arm(&self, arm: ArmId) -> &ArmStatus {
        &self.0[arm.index()]
    }

    /// Mutable status of `arm`.
    pub fn arm_mut(&mut self, arm: ArmId) -> &mut ArmStatus {
        &mut self.0[arm.index()]
    }
}

/// What an arm asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Request {
    /// Leave the drop-off towards the next assigned apple (eq. 8, first clause).
    StartApproach,
    /// Open the source valve at the apple to attempt attachment (eq. 8 second clause, eq. 11).
    OpenValve,
}

impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Request::StartApproach => f.write_str("start approach"),
            Request::OpenValve => f.write_str("open valve"),
        }
    }
}

/// Why a request was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RefuseReason {
    /// The requesting arm is not at the drop-off ready for a new cycle (eq. 8, first clause).
    NotReady {
        /// Its phase.
        phase: CoordinationPhase,
    },
    /// No apple is assigned to the requesting arm (eq. 8, first clause).
    NoAppleAssigned,
    /// The requesting arm is not at its apple (eq. 8, second clause).
    NotAtApple {
        /// Its phase.
        phase: CoordinationPhase,
    },
    /// The requesting arm's valve is already open.
    ValveAlreadyOpen,
    /// The other arm's valve is open and its cup is not sealed: it is attempting attachment
    /// (eq. 11, third and fourth clauses).
    OtherArmAttempting,
    /// The other arm's valve is open after a detected failure and is about to be closed.
    OtherArmFailing,
    /// 2023 policy: the other arm holds the vacuum from its attach to the end of its release.
    VacuumHeldByOther {
        /// The other arm's phase.
        other_phase: CoordinationPhase,
    },
    /// Baseline: the other arm is in the middle of its cycle; the arms run one after the other.
    OtherArmActive {
        /// The other arm's phase.
        other_phase: CoordinationPhase,
    },
}

impl fmt::Display for RefuseReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RefuseReason::NotReady { phase } => write!(f, "arm not ready (phase {phase})"),
            RefuseReason::NoAppleAssigned => f.write_str("no apple assigned"),
            RefuseReason::NotAtApple { phase } => write!(f, "arm not at its apple ({phase})"),
            RefuseReason::ValveAlreadyOpen => f.write_str("valve already open"),
            RefuseReason::OtherArmAttempting => f.write_str("other arm is attempting attachment"),
            RefuseReason::OtherArmFailing => f.write_str("other arm's failed valve is closing"),
            RefuseReason::VacuumHeldByOther { other_phase } => {
                write!(f, "vacuum held by the other arm ({other_phase})")
            }
            RefuseReason::OtherArmActive { other_phase } => {
                write!(f, "other arm is active ({other_phase})")
            }
        }
    }
}

/// A policy's answer to a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Decision {
    /// Go ahead.
    Grant,
    /// Not now; ask again when the snapshot changes.
    Refuse(RefuseReason),
}

/// Why a valve must close now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CloseReason {
    /// No seal formed within the attach timeout (eq. 11, first two clauses).
    AttachFailed,
    /// The seal was lost with the valve open (eq. 11, first two clauses).
    Dropped,
    /// The attach window ended without a seal: the arm retracts, so the attempt is over
    /// (eq. 8 third clause with eq. 11 first two clauses).
    NoSealAtRetract,
    /// The arm is at the drop-off: closing vents the tube and releases the apple (eq. 8,
    /// fourth clause).
    Release,
    /// The valve is open in a phase where the workflow never opens it (eq. 8, second clause).
    OutOfWorkflow {
        /// The arm's phase.
        phase: CoordinationPhase,
    },
}

impl fmt::Display for CloseReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CloseReason::AttachFailed => f.write_str("failed attachment"),
            CloseReason::Dropped => f.write_str("apple dropped"),
            CloseReason::NoSealAtRetract => f.write_str("no seal at the end of the attach window"),
            CloseReason::Release => f.write_str("release at the drop-off"),
            CloseReason::OutOfWorkflow { phase } => write!(f, "valve open while {phase}"),
        }
    }
}

/// What must happen to one arm's valve now.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ValveOrder {
    /// Leave it as it is.
    Keep,
    /// Close it within this control period.
    ForceClose(CloseReason),
}

/// A vacuum coordination policy. Implementations are pure functions of the snapshot (no clock,
/// no I/O), so the same object can be driven by the cycle model, the simulator or the robot.
pub trait VacuumPolicy {
    /// Which policy this is.
    fn kind(&self) -> PolicyKind;

    /// Decide on `request` from `arm` given both arms' current status.
    fn decide(&self, arm: ArmId, request: Request, arms: &PairStatus) -> Decision;

    /// The valves that must close now, indexed by [`ArmId::index`].
    fn supervise(&self, arms: &PairStatus) -> [ValveOrder; 2];
}

/// The available policies (section 4.2, Fig. 12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PolicyKind {
    /// No coordination: strictly sequential arms.
    Baseline,
    /// The 2023 dual-arm version (Lammers et al. 2024): parallel approach, exclusive vacuum.
    V2023,
    /// The 2024 failure-aware temporal-logic policy (eq. 7-12).
    V2024,
}

impl PolicyKind {
    /// All policies, in the order of Fig. 12.
    pub const ALL: [PolicyKind; 3] = [PolicyKind::Baseline, PolicyKind::V2023, PolicyKind::V2024];
}

impl fmt::Display for PolicyKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PolicyKind::Baseline => f.write_str("baseline"),
            PolicyKind::V2023 => f.write_str("2023"),
            PolicyKind::V2024 => f.write_str("2024"),
        }
    }
}

/// The one place where a policy kind becomes an implementation.
pub fn new_policy(kind: PolicyKind) -> Box<dyn VacuumPolicy + Send + Sync> {
    match kind {
        PolicyKind::Baseline => Box::new(SequentialBaseline),
        PolicyKind::V2023 => Box::new(Staggered2023),
        PolicyKind::V2024 => Box::new(FailureAware2024),
    }
}

/// Preconditions on the requesting arm itself, shared by every policy (eq. 8, first and second
/// clauses): an approach starts from the drop-off with an apple assigned and the valve closed;
/// a valve opens only at the apple.
pub fn own_preconditions(own: &ArmStatus, request: Request) -> Result<(), RefuseReason> {
    match request {
        Request::StartApproach => {
            if own.phase != CoordinationPhase::Ready {
                Err(RefuseReason::NotReady { phase: own.phase })
            } else if own.valve_open {
                Err(RefuseReason::ValveAlreadyOpen)
            } else if !own.apple_assigned {
                Err(RefuseReason::NoAppleAssigned)
            } else {
                Ok(())
            }
        }
        Request::OpenValve => {
            if own.phase != CoordinationPhase::AtApple {
                Err(RefuseReason::NotAtApple { phase: own.phase })
            } else if own.valve_open {
                Err(RefuseReason::ValveAlreadyOpen)
            } else {
                Ok(())
            }
        }
    }
}

/// The release and workflow closes shared by every policy: a valve open at the drop-off is
/// closed to release (eq. 8, fourth clause); a valve open while approaching or waiting is
/// closed as out of workflow.
pub fn workflow_close(own: &ArmStatus) -> ValveOrder {
    if !own.valve_open {
        return ValveOrder::Keep;
    }
    match own.phase {
        CoordinationPhase::Releasing => ValveOrder::ForceClose(CloseReason::Release),
        CoordinationPhase::Ready | CoordinationPhase::Approaching | CoordinationPhase::AtApple => {
            ValveOrder::ForceClose(CloseReason::OutOfWorkflow { phase: own.phase })
        }
        CoordinationPhase::Attaching | CoordinationPhase::Retracting => ValveOrder::Keep,
    }
}

#[cfg(test)]
mod conformance;
