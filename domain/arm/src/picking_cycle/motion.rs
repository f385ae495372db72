//! A planned [`Motion`] of the arm and its progress: planning from the measured joints,
//! re-planning after a feedback outage, arrival within tolerance.

use tracing::warn;

use super::state::{AttachStage, State};
use super::{CycleInput, PickingCycle};
use crate::controller::TrackingReference;
use crate::trajectory::JointTrajectory;
use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::kinematics::forward;

/// A trajectory being followed. Without a trajectory (planning failed, which valid goals
/// never cause) the reference is the goal itself and the rate clamps pace the motion.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Motion {
    pub(super) trajectory: Option<JointTrajectory>,
    pub(super) start_ns: u64,
    pub(super) goal: JointPosition,
}

impl Motion {
    pub(super) fn duration_s(&self) -> f64 {
        self.trajectory
            .as_ref()
            .map_or(0.0, JointTrajectory::duration_s)
    }

    pub(super) fn reference(
        &self,
        links: &harvest_robot_model::params::LinkParams,
        t_s: f64,
    ) -> TrackingReference {
        match &self.trajectory {
            Some(trajectory) => {
                TrackingReference::from_joint_sample(links, &trajectory.sample(t_s))
            }
            None => TrackingReference::hold(links, &self.goal),
        }
    }
}

/// Progress of a motion at one step.
pub(super) enum MotionProgress {
    Running,
    Arrived,
    TimedOut,
}

/// Time from `since_ns` to `now_ns`, s (0 when `now_ns` is earlier).
pub(super) fn elapsed_s(now_ns: u64, since_ns: u64) -> f64 {
    now_ns.saturating_sub(since_ns) as f64 * 1e-9
}

/// Euclidean distance, m.
pub(super) fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl PickingCycle {
    /// Plans a motion from the measured joints to `goal`, starting now at rest.
    pub(super) fn motion_to(&self, input: &CycleInput, goal: JointPosition) -> Motion {
        self.motion_via(input, None, goal)
    }

    /// Plans a motion from the measured joints through `via` (if any) to `goal`, starting now
    /// at rest.
    pub(super) fn motion_via(
        &self,
        input: &CycleInput,
        via: Option<JointPosition>,
        goal: JointPosition,
    ) -> Motion {
        let all = [input.joints, via.unwrap_or(goal), goal];
        let waypoints = if via.is_some() { &all[..] } else { &all[..2] };
        let trajectory = JointTrajectory::plan(
            &self.params,
            waypoints,
            &JointVelocity::ZERO,
            self.config.speed_fraction,
        )
        .inspect_err(|error| {
            warn!(arm = %self.params.arm, %error, "motion planning failed: direct regulation");
        })
        .ok();
        Motion {
            trajectory,
            start_ns: input.now_ns,
            goal,
        }
    }

    /// After a feedback outage the arm was stopped: restart the running motion from where the
    /// arm is, at rest.
    pub(super) fn replan(&mut self, input: &CycleInput) {
        self.needs_replan = false;
        let goal = match &self.state {
            State::Approach { motion, .. } | State::Retract { motion, .. } => motion.goal,
            State::Attach {
                stage: AttachStage::Twisting { motion },
                ..
            } => motion.goal,
            _ => return,
        };
        let fresh = self.motion_to(input, goal);
        match &mut self.state {
            State::Approach { motion, .. }
            | State::Retract { motion, .. }
            | State::Attach {
                stage: AttachStage::Twisting { motion },
                ..
            } => *motion = fresh,
            _ => {}
        }
    }

    pub(super) fn progress(&self, motion: &Motion, input: &CycleInput) -> MotionProgress {
        let t = elapsed_s(input.now_ns, motion.start_ns);
        let duration = motion.duration_s();
        if t < duration {
            return MotionProgress::Running;
        }
        let links = &self.params.links;
        let position_error =
            distance_m(forward(links, &input.joints), forward(links, &motion.goal));
        let twist_error = (input.joints.twist_rad - motion.goal.twist_rad).abs();
        if position_error <= self.config.arrival_tolerance_m
            && twist_error <= self.config.twist_tolerance_rad
        {
            MotionProgress::Arrived
        } else if t >= duration + self.config.settle_timeout_s {
            MotionProgress::TimedOut
        } else {
            MotionProgress::Running
        }
    }
}
