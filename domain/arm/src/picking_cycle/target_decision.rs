//! The answer to an offered target: [`TargetDecision`], and [`TargetRejection`] when refused.

use thiserror::Error;

use super::CyclePhase;
use crate::trajectory::TrajectoryError;
use harvest_robot_model::kinematics::IkError;

/// Why a target was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TargetRejection {
    /// The position has a NaN or infinite coordinate.
    #[error("target {id} position {position_m:?} is not finite")]
    NonFinite {
        /// Target id.
        id: u64,
        /// The position.
        position_m: [f64; 3],
    },
    /// The detection is older than the configured maximum.
    #[error("target {id} is stale: detected {age_s:.3} s ago, maximum {max_age_s:.3} s")]
    Stale {
        /// Target id.
        id: u64,
        /// Age of the detection, s.
        age_s: f64,
        /// Configured maximum, s.
        max_age_s: f64,
    },
    /// The detection time is after `now_ns`.
    #[error("target {id} is stamped {ahead_s:.6} s in the future")]
    FromFuture {
        /// Target id.
        id: u64,
        /// How far ahead, s.
        ahead_s: f64,
    },
    /// The target is outside this arm's workspace.
    #[error("target {id} is unreachable: {reason}")]
    Unreachable {
        /// Target id.
        id: u64,
        /// Why (inverse kinematics).
        reason: IkError,
    },
    /// This arm is in a cycle already (retry when Idle).
    #[error("target {id} refused: arm busy in phase {phase:?}")]
    Busy {
        /// Target id.
        id: u64,
        /// Current phase.
        phase: CyclePhase,
    },
    /// The motion would pass closer to the other arm than the clearance (retry later).
    #[error(
        "target {id} refused: swept paths come within {min_distance_m:.3} m of the other arm (clearance {clearance_m:.3} m)"
    )]
    ClearanceConflict {
        /// Target id.
        id: u64,
        /// Smallest tube-to-tube distance found, m.
        min_distance_m: f64,
        /// Configured clearance, m.
        clearance_m: f64,
    },
    /// The other arm is approaching but did not report its goal (retry later).
    #[error("target {id} refused: the other arm is approaching an unknown goal")]
    OtherArmGoalUnknown {
        /// Target id.
        id: u64,
    },
    /// The other arm's reported position has no kinematic solution.
    #[error("target {id} refused: other arm pose unknown ({reason})")]
    OtherArmPoseUnknown {
        /// Target id.
        id: u64,
        /// Why its position could not be inverted.
        reason: IkError,
    },
    /// Joint feedback is invalid or stale, so no motion can start (retry when it recovers).
    #[error("target {id} refused: joint feedback invalid or stale")]
    NoFeedback {
        /// Target id.
        id: u64,
    },
    /// No trajectory could be planned.
    #[error("target {id} refused: planning failed: {reason}")]
    Planning {
        /// Target id.
        id: u64,
        /// Planner error.
        reason: TrajectoryError,
    },
}

impl TargetRejection {
    /// True when the same target may be offered again later (the refusal depends on this or
    /// the other arm's current activity, not on the target itself).
    pub fn is_retryable(&self) -> bool {
        matches!(
            self,
            TargetRejection::Busy { .. }
                | TargetRejection::NoFeedback { .. }
                | TargetRejection::ClearanceConflict { .. }
                | TargetRejection::OtherArmGoalUnknown { .. }
        )
    }
}

/// The answer to an offered target.
#[derive(Debug, Clone, PartialEq)]
pub enum TargetDecision {
    /// The cycle started; the arm is approaching.
    Accepted {
        /// Target id.
        id: u64,
    },
    /// The target was refused.
    Rejected(TargetRejection),
}
