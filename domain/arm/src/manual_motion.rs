//! Manual motion of one arm: a rest-to-rest joint-space move to a goal the operator chose (a
//! jogged joint, the drop-off pose), at a fraction of the arm's rate limits. The executive plans
//! the same move to tell the operator how long it takes ([`plan_duration_s`]); the arm node runs
//! it ([`crate::node::ArmNode::start_manual`]) only while its picking cycle is idle.
//!
//! The move is a quintic in joint space ([`JointTrajectory::plan`] with two waypoints), so each
//! joint goes monotonically from start to goal and never leaves the box the two span: a goal
//! inside the Table 1 limits keeps the whole move inside them.

use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::params::ArmParams;
use thiserror::Error;

use crate::trajectory::{JointTrajectory, TrajectoryError};

/// Share of the rate limits a manual move uses by default (choice: a quarter, so an operator
/// watching the arm can follow it and press the stop in time; 0.19 m/s at the tube tip).
pub const MANUAL_SPEED_FRACTION: f64 = 0.25;

/// Why a manual move cannot be planned.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ManualMotionError {
    /// The goal is outside the arm's joint limits (joint index, value, limits).
    #[error("joint {joint} goal {value:.4} outside the limits [{min:.4}, {max:.4}]")]
    OutsideLimits {
        /// Joint index 0-3 (`D`, `theta`, `phi`, twist).
        joint: usize,
        /// The goal value, m or rad.
        value: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// The start or the goal is not finite.
    #[error("manual move: start or goal not finite")]
    NotFinite,
    /// The trajectory could not be planned.
    #[error("manual move: {0}")]
    Trajectory(#[from] TrajectoryError),
}

/// The first joint of `goal` outside `params`' limits, as an error.
pub fn check_limits(params: &ArmParams, goal: &[f64; 4]) -> Result<(), ManualMotionError> {
    let lo = params.position_limits.min.to_array();
    let hi = params.position_limits.max.to_array();
    for joint in 0..4 {
        let value = goal[joint];
        if !value.is_finite() {
            return Err(ManualMotionError::NotFinite);
        }
        if value < lo[joint] || value > hi[joint] {
            return Err(ManualMotionError::OutsideLimits {
                joint,
                value,
                min: lo[joint],
                max: hi[joint],
            });
        }
    }
    Ok(())
}

fn plan(
    params: &ArmParams,
    from: &[f64; 4],
    goal: &[f64; 4],
    speed_fraction: f64,
) -> Result<JointTrajectory, ManualMotionError> {
    check_limits(params, goal)?;
    if from.iter().any(|v| !v.is_finite()) {
        return Err(ManualMotionError::NotFinite);
    }
    // Encoder noise may put the start a hair outside a limit: the move starts from the clamped
    // pose (the trajectory planner checks only the waypoints after the first).
    let start = params
        .position_limits
        .clamp(&JointPosition::from_array(*from));
    let trajectory = JointTrajectory::plan(
        params,
        &[start, JointPosition::from_array(*goal)],
        &JointVelocity::default(),
        speed_fraction,
    )?;
    Ok(trajectory)
}

/// How long a manual move from `from` to `goal` takes, s.
pub fn plan_duration_s(
    params: &ArmParams,
    from: &[f64; 4],
    goal: &[f64; 4],
    speed_fraction: f64,
) -> Result<f64, ManualMotionError> {
    Ok(plan(params, from, goal, speed_fraction)?.duration_s())
}

/// A manual move under way.
#[derive(Debug, Clone, PartialEq)]
pub struct ManualMotion {
    trajectory: JointTrajectory,
    start_ns: u64,
    request_id: u64,
}

/// The set-point of a manual move at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManualSetpoint {
    /// `[D m, theta rad, phi rad, twist rad]`.
    pub position: [f64; 4],
    /// `[m/s, rad/s, rad/s, rad/s]`.
    pub velocity: [f64; 4],
    /// True once the move's time is over (the set-point is the goal, at rest).
    pub finished: bool,
}

impl ManualMotion {
    /// Plans the move from `from` (the arm at rest) to `goal`, starting at `start_ns`.
    pub fn plan(
        params: &ArmParams,
        from: &[f64; 4],
        goal: &[f64; 4],
        speed_fraction: f64,
        start_ns: u64,
        request_id: u64,
    ) -> Result<Self, ManualMotionError> {
        Ok(Self {
            trajectory: plan(params, from, goal, speed_fraction)?,
            start_ns,
            request_id,
        })
    }

    /// Duration of the move, s.
    pub fn duration_s(&self) -> f64 {
        self.trajectory.duration_s()
    }

    /// The operator request behind the move.
    pub fn request_id(&self) -> u64 {
        self.request_id
    }

    /// The set-point at `now_ns`.
    pub fn setpoint(&self, now_ns: u64) -> ManualSetpoint {
        let t_s = now_ns.saturating_sub(self.start_ns) as f64 * 1e-9;
        let sample = self.trajectory.sample(t_s);
        let finished = t_s >= self.trajectory.duration_s();
        ManualSetpoint {
            position: sample.position.to_array(),
            velocity: if finished {
                [0.0; 4]
            } else {
                sample.velocity.to_array()
            },
            finished,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_jog_inside_the_limits_runs_from_start_to_goal_and_stays_inside() {
        let params = ArmParams::arm1();
        let from = params.home.to_array();
        let mut goal = from;
        goal[1] += 0.2;
        let motion = ManualMotion::plan(&params, &from, &goal, MANUAL_SPEED_FRACTION, 1_000, 7)
            .expect("plan");
        assert_eq!(motion.request_id(), 7);
        let duration_ns = (motion.duration_s() * 1e9) as u64;
        let start = motion.setpoint(1_000);
        assert!((start.position[1] - from[1]).abs() < 1e-9);
        assert!(!start.finished);
        let mut previous = from[1];
        for step in 1..=20 {
            let sample = motion.setpoint(1_000 + duration_ns * step / 20);
            assert!(sample.position[1] >= previous - 1e-12, "monotonic");
            assert!(
                params
                    .position_limits
                    .contains(&JointPosition::from_array(sample.position))
            );
            previous = sample.position[1];
        }
        let end = motion.setpoint(1_000 + duration_ns + 1);
        assert!(end.finished);
        assert!((end.position[1] - goal[1]).abs() < 1e-9);
        assert_eq!(end.velocity, [0.0; 4]);
        let planned = plan_duration_s(&params, &from, &goal, MANUAL_SPEED_FRACTION).expect("plan");
        assert_eq!(planned, motion.duration_s());
    }

    #[test]
    fn goals_outside_the_limits_or_not_finite_are_refused() {
        let params = ArmParams::arm2();
        let from = params.home.to_array();
        let mut goal = from;
        goal[0] = params.position_limits.max.d_m + 0.01;
        assert!(matches!(
            ManualMotion::plan(&params, &from, &goal, 0.5, 0, 1),
            Err(ManualMotionError::OutsideLimits { joint: 0, .. })
        ));
        goal[0] = f64::NAN;
        assert_eq!(
            check_limits(&params, &goal),
            Err(ManualMotionError::NotFinite)
        );
    }
}
