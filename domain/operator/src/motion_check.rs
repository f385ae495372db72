//! Checks of a manual move before anything moves: the arm is known, idle and at rest; a jog is
//! small and its goal inside the Table 1 joint limits; the swept tube keeps the picking
//! cycle's clearance from the other arm (`harvest_robot_model::clearance`).

use harvest_arm::manual_motion::plan_duration_s;
use harvest_ipc::payloads::ArmPhase;
use harvest_robot_model::clearance::SweptPath;
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::params::{ArmId, ArmParams};

use crate::command::JointName;
use crate::refusal::Refusal;
use crate::stack_view::ArmView;

/// Tube bodies sampled along each straight joint-space line of the clearance check.
const SWEEP_SAMPLES: usize = 16;

/// Limits of manual moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionLimits {
    /// Largest jog of the prismatic joint, m.
    pub max_jog_m: f64,
    /// Largest jog of a revolute joint, rad.
    pub max_jog_rad: f64,
    /// Closest the two tubes may come, m.
    pub clearance_m: f64,
    /// Joint rates below this count as at rest (m/s or rad/s).
    pub at_rest_rate: f64,
    /// Oldest arm state a move may start from, ns.
    pub max_state_age_ns: u64,
    /// Share of the rate limits a manual move uses.
    pub speed_fraction: f64,
}

/// The robot-model id of arm number 1 or 2.
pub fn arm_id(arm: u8) -> ArmId {
    if arm == 2 { ArmId::Arm2 } else { ArmId::Arm1 }
}

/// The arm's view if it is known, fresh, idle and at rest.
pub fn idle_at_rest(
    arm: u8,
    view: Option<&ArmView>,
    limits: &MotionLimits,
) -> Result<ArmView, Refusal> {
    let view = view
        .filter(|v| v.age_ns <= limits.max_state_age_ns)
        .ok_or(Refusal::ArmStateUnknown(arm))?;
    match view.phase {
        Some(ArmPhase::Idle) => {}
        Some(phase) => {
            return Err(Refusal::ArmBusy {
                arm,
                what: format!("{phase:?}").to_lowercase(),
            });
        }
        None => return Err(Refusal::ArmStateUnknown(arm)),
    }
    if view
        .joint_velocity
        .iter()
        .any(|rate| !rate.is_finite() || rate.abs() > limits.at_rest_rate)
    {
        return Err(Refusal::ArmBusy {
            arm,
            what: "still moving".to_owned(),
        });
    }
    Ok(*view)
}

/// The goal of a jog of `joint` by `delta` from `from`, inside the limits.
pub fn jog_goal(
    arm: u8,
    from: &[f64; 4],
    joint: JointName,
    delta: f64,
    limits: &MotionLimits,
) -> Result<[f64; 4], Refusal> {
    let max = if joint == JointName::D {
        limits.max_jog_m
    } else {
        limits.max_jog_rad
    };
    if !delta.is_finite() || delta.abs() > max {
        return Err(Refusal::BadArgument(format!(
            "jog of {} by {delta} {}: at most {max} {} per command",
            joint.name(),
            joint.unit(),
            joint.unit()
        )));
    }
    let mut goal = *from;
    goal[joint.index()] += delta;
    check_joint_limits(arm, &goal)?;
    Ok(goal)
}

/// The first joint of `goal` outside arm `arm`'s limits, as a refusal.
pub fn check_joint_limits(arm: u8, goal: &[f64; 4]) -> Result<(), Refusal> {
    let params = ArmParams::for_arm(arm_id(arm));
    let lo = params.position_limits.min.to_array();
    let hi = params.position_limits.max.to_array();
    for joint in JointName::ALL {
        let i = joint.index();
        let value = goal[i];
        if !(value.is_finite() && value >= lo[i] && value <= hi[i]) {
            return Err(Refusal::JointOutsideLimits {
                arm,
                joint: joint.name(),
                value,
                min: lo[i],
                max: hi[i],
            });
        }
    }
    Ok(())
}

/// Refuses a move of arm `arm` from `from` to `goal` whose swept tube comes closer than the
/// clearance to the other arm moving (or resting) from `other_from` to `other_goal`.
pub fn check_clearance(
    arm: u8,
    from: &[f64; 4],
    goal: &[f64; 4],
    other_from: &[f64; 4],
    other_goal: &[f64; 4],
    limits: &MotionLimits,
) -> Result<(), Refusal> {
    let ours_params = ArmParams::for_arm(arm_id(arm));
    let theirs_params = ArmParams::for_arm(arm_id(3 - arm));
    let mut ours = SweptPath::new();
    ours.push_joint_line(
        &ours_params.links,
        &JointPosition::from_array(*from),
        &JointPosition::from_array(*goal),
        SWEEP_SAMPLES,
    );
    let mut theirs = SweptPath::new();
    theirs.push_joint_line(
        &theirs_params.links,
        &JointPosition::from_array(*other_from),
        &JointPosition::from_array(*other_goal),
        SWEEP_SAMPLES,
    );
    let distance_m = ours.min_distance_m(&theirs);
    if distance_m < limits.clearance_m {
        return Err(Refusal::Clearance {
            arm,
            distance_m,
            clearance_m: limits.clearance_m,
        });
    }
    Ok(())
}

/// Planned duration of the move, ms (what the arm will take, `harvest_arm::manual_motion`).
pub fn duration_ms(
    arm: u8,
    from: &[f64; 4],
    goal: &[f64; 4],
    limits: &MotionLimits,
) -> Result<u32, Refusal> {
    let params = ArmParams::for_arm(arm_id(arm));
    let seconds = plan_duration_s(&params, from, goal, limits.speed_fraction)
        .map_err(|error| Refusal::BadArgument(format!("arm {arm}: {error}")))?;
    Ok((seconds * 1000.0).ceil().min(f64::from(u32::MAX)) as u32)
}

/// Arm `arm`'s drop-off (home) pose.
pub fn drop_off_pose(arm: u8) -> [f64; 4] {
    ArmParams::for_arm(arm_id(arm)).home.to_array()
}
