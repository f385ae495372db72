//! What one step of the picking cycle reads: [`CycleInput`], with the offered
//! [`TargetRequest`] and the other arm's [`OtherArmState`].

use serde::{Deserialize, Serialize};

use super::{CycleOutput, CyclePhase};
use harvest_robot_model::joint::JointPosition;

/// A target assigned to this arm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetRequest {
    /// Identifier chosen by the assigner; repeats of the current target are ignored.
    pub id: u64,
    /// Picking point in the robot frame, m.
    pub position_m: [f64; 3],
    /// Capture time of the image the target was detected in, ns (same clock as `now_ns`).
    pub detected_at_ns: u64,
}

/// What this arm needs to know about the other arm for the clearance check.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OtherArmState {
    /// Its phase.
    pub phase: CyclePhase,
    /// Its end-effector position, robot frame, m.
    pub end_effector_m: [f64; 3],
    /// Where it is moving to, robot frame, m (required while it approaches).
    pub goal_m: Option<[f64; 3]>,
}

impl OtherArmState {
    /// The state another [`PickingCycle`](super::PickingCycle) reported in its last output.
    pub fn from_output(output: &CycleOutput) -> Self {
        Self {
            phase: output.phase,
            end_effector_m: output.end_effector_m,
            goal_m: output.goal_m,
        }
    }
}

/// Inputs of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleInput {
    /// Current time, ns (monotonic).
    pub now_ns: u64,
    /// Measured joint positions.
    pub joints: JointPosition,
    /// Time the joint positions were measured, ns.
    pub joints_stamp_ns: u64,
    /// True when this arm's valve is open to the vacuum source (the grant of our request).
    pub valve_open: bool,
    /// True when the pressure sensor of this arm says an apple seals the end-effector.
    pub apple_attached: bool,
    /// A target offered to this arm this step, if any.
    pub target: Option<TargetRequest>,
    /// The other arm's state; `None` when there is no other arm (single-arm operation).
    pub other_arm: Option<OtherArmState>,
}
