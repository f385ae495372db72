//! What one step of the picking cycle returns: [`CycleOutput`], with the [`ValveRequest`].

use serde::{Deserialize, Serialize};

use super::{CycleEvent, CyclePhase, TargetDecision};
use crate::controller::{JointCommand, TrackingReference};

/// What this arm asks of its valves (Fig. 3): open to the vacuum source (attach and hold) or
/// closed to the source and open to the atmosphere (release, and the resting state).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ValveRequest {
    /// Closed to the vacuum source, vented (paper: `not Open_Valve`).
    Closed,
    /// Open to the vacuum source (paper: `Open_Valve`).
    Open,
}

/// Outputs of one step.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleOutput {
    /// Phase after this step.
    pub phase: CyclePhase,
    /// Joint rate command for the servos.
    pub command: JointCommand,
    /// Requested valve state.
    pub valve_request: ValveRequest,
    /// Answer to the target offered this step, if any and not a repeat.
    pub target_decision: Option<TargetDecision>,
    /// Event of this step, if any.
    pub event: Option<CycleEvent>,
    /// Measured end-effector position, robot frame, m.
    pub end_effector_m: [f64; 3],
    /// End-effector goal of the current or next motion, robot frame, m.
    pub goal_m: Option<[f64; 3]>,
    /// Tracking reference used this step (for logging).
    pub reference: Option<TrackingReference>,
    /// Id of the target of the running cycle.
    pub target_id: Option<u64>,
}
