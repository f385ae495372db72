//! The clearance check against the other arm: a target is refused while the swept paths of
//! both arms would come closer than [`super::CycleConfig::clearance_m`].

use super::{CyclePhase, OtherArmState, PickingCycle, TargetRejection};
use crate::trajectory::JointTrajectory;
use harvest_robot_model::clearance::SweptPath;
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::kinematics::inverse_unchecked;

/// Samples of our own planned approach used for the clearance check.
const OWN_SWEEP_SAMPLES: usize = 16;
/// Samples of each straight joint-space leg used for the clearance check.
const LEG_SWEEP_SAMPLES: usize = 8;

impl PickingCycle {
    /// Refuses the motion when our sweep (approach, then straight back home) comes closer to
    /// the other arm's remaining sweep than the clearance.
    pub(super) fn check_clearance(
        &self,
        id: u64,
        approach: &JointTrajectory,
        goal: &JointPosition,
        other: &OtherArmState,
    ) -> Result<(), TargetRejection> {
        let links = &self.params.links;
        let mut ours = SweptPath::new();
        for k in 0..=OWN_SWEEP_SAMPLES {
            let t = approach.duration_s() * k as f64 / OWN_SWEEP_SAMPLES as f64;
            ours.push(links, &approach.sample(t).position);
        }
        ours.push_joint_line(links, goal, &self.params.home, LEG_SWEEP_SAMPLES);

        let other_links = &self.other_params.links;
        let other_home = self.other_params.home;
        let now = inverse_unchecked(other_links, other.end_effector_m)
            .map_err(|reason| TargetRejection::OtherArmPoseUnknown { id, reason })?;
        let mut theirs = SweptPath::new();
        match other.phase {
            CyclePhase::Idle | CyclePhase::Release => {
                theirs.push(other_links, &now);
            }
            CyclePhase::Attach => {
                theirs.push_joint_line(other_links, &now, &other_home, LEG_SWEEP_SAMPLES);
            }
            CyclePhase::Retract => {
                let goal = match other.goal_m {
                    Some(g) => inverse_unchecked(other_links, g)
                        .map_err(|reason| TargetRejection::OtherArmPoseUnknown { id, reason })?,
                    None => other_home,
                };
                theirs.push_joint_line(other_links, &now, &goal, LEG_SWEEP_SAMPLES);
            }
            CyclePhase::Approach => {
                let goal_m = other
                    .goal_m
                    .ok_or(TargetRejection::OtherArmGoalUnknown { id })?;
                let goal = inverse_unchecked(other_links, goal_m)
                    .map_err(|reason| TargetRejection::OtherArmPoseUnknown { id, reason })?;
                theirs.push_joint_line(other_links, &now, &goal, LEG_SWEEP_SAMPLES);
                theirs.push_joint_line(other_links, &goal, &other_home, LEG_SWEEP_SAMPLES);
            }
        }
        let min_distance_m = ours.min_distance_m(&theirs);
        if min_distance_m < self.config.clearance_m {
            return Err(TargetRejection::ClearanceConflict {
                id,
                min_distance_m,
                clearance_m: self.config.clearance_m,
            });
        }
        Ok(())
    }
}
