//! The internal state of the picking cycle: one variant per phase with the data that phase
//! needs, and the [`Transition`] a phase's step returns.

use super::motion::Motion;
use super::{CycleEvent, CyclePhase, TargetRequest, ValveRequest};
use harvest_robot_model::joint::JointPosition;

#[derive(Debug, Clone, PartialEq)]
#[allow(
    clippy::large_enum_variant,
    reason = "motions hold their trajectory in fixed arrays so a control tick allocates nothing; boxing would allocate"
)]
pub(super) enum AttachStage {
    WaitingValve { since_ns: u64 },
    WaitingAttachment { since_ns: u64 },
    Twisting { motion: Motion },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum ReleaseStage {
    WaitingValveClosed { since_ns: u64 },
    Dropping { since_ns: u64 },
}

#[derive(Debug, Clone, PartialEq)]
pub(super) enum State {
    Idle,
    Approach {
        motion: Motion,
        target: TargetRequest,
    },
    Attach {
        target: TargetRequest,
        hold: JointPosition,
        stage: AttachStage,
    },
    Retract {
        motion: Motion,
        target_id: u64,
        apple: bool,
    },
    Release {
        target_id: u64,
        stage: ReleaseStage,
    },
}

impl State {
    pub(super) fn phase(&self) -> CyclePhase {
        match self {
            State::Idle => CyclePhase::Idle,
            State::Approach { .. } => CyclePhase::Approach,
            State::Attach { .. } => CyclePhase::Attach,
            State::Retract { .. } => CyclePhase::Retract,
            State::Release { .. } => CyclePhase::Release,
        }
    }

    pub(super) fn target_id(&self) -> Option<u64> {
        match self {
            State::Idle => None,
            State::Approach { target, .. } | State::Attach { target, .. } => Some(target.id),
            State::Retract { target_id, .. } | State::Release { target_id, .. } => Some(*target_id),
        }
    }

    /// The valve this state asks for: open from the end of the approach through the attachment
    /// and a retract that holds an apple; closed otherwise, so a failed attachment or an apple
    /// lost on the way back closes it at once (eq. 11).
    pub(super) fn valve_request(&self) -> ValveRequest {
        match self {
            State::Attach { .. } | State::Retract { apple: true, .. } => ValveRequest::Open,
            State::Idle
            | State::Approach { .. }
            | State::Retract { apple: false, .. }
            | State::Release { .. } => ValveRequest::Closed,
        }
    }
}

/// What the step of the current phase decided; `PickingCycle::advance` applies it.
#[derive(Debug)]
#[allow(
    clippy::large_enum_variant,
    reason = "motions hold their trajectory in fixed arrays so a control tick allocates nothing; boxing would allocate"
)]
pub(super) enum Transition {
    /// Keep the current state (still moving or waiting); nothing happened.
    Stay,
    /// Replace the current state, with the step's event, if any.
    To {
        /// The next state.
        state: State,
        /// What happened.
        event: Option<CycleEvent>,
    },
}

impl Transition {
    /// To `state` with `event`.
    pub(super) fn to(state: State, event: CycleEvent) -> Self {
        Transition::To {
            state,
            event: Some(event),
        }
    }

    /// To `state` without an event (a stage change inside a phase).
    pub(super) fn quietly(state: State) -> Self {
        Transition::To { state, event: None }
    }
}
