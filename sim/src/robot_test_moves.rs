//! Test helpers that drive the simulated robot as a controller would: stepping the physics,
//! streaming joint set-points, finding the apple nearest an arm.

use crate::orchard::Apple;
use crate::physics::WorldEvent;
use crate::robot::SimRobot;
use harvest_ipc::ArmId;

/// The physics step the helpers use, s.
pub const DT: f64 = 0.005;

/// Steps the robot for `seconds`; returns the world's events.
pub fn run(robot: &mut SimRobot, seconds: f64) -> Vec<WorldEvent> {
    let mut all = Vec::new();
    for _ in 0..(seconds / DT).round() as usize {
        all.extend(robot.step(DT).expect("step"));
    }
    all
}

/// Streams set-points that move `arm` linearly in joint space to `goal` over `seconds`, then
/// holds the goal for 0.5 s.
pub fn move_to(robot: &mut SimRobot, arm: ArmId, goal: [f64; 4], seconds: f64) -> Vec<WorldEvent> {
    let (start, _) = robot.encoders(arm);
    let steps = (seconds / DT).round() as usize;
    let velocity: [f64; 4] = std::array::from_fn(|j| (goal[j] - start[j]) / seconds);
    let mut events = Vec::new();
    for k in 0..steps {
        let s = k as f64 / steps as f64;
        let position = std::array::from_fn(|j| start[j] + (goal[j] - start[j]) * s);
        robot
            .set_servo_setpoint(arm, position, velocity)
            .expect("set-point");
        events.extend(robot.step(DT).expect("step"));
    }
    for _ in 0..100 {
        robot
            .set_servo_setpoint(arm, goal, [0.0; 4])
            .expect("set-point");
        events.extend(robot.step(DT).expect("step"));
    }
    events
}

/// The apple whose centre is nearest `arm`'s cup.
pub fn nearest_apple(robot: &SimRobot, arm: ArmId) -> Apple {
    let cup_m = robot.end_effector_in_robot_m(arm);
    let distance_m2 = |apple: &Apple| {
        (0..3)
            .map(|i| (apple.center_in_robot_m[i] - cup_m[i]).powi(2))
            .sum::<f64>()
    };
    robot
        .world()
        .apples()
        .iter()
        .min_by(|a, b| distance_m2(a).total_cmp(&distance_m2(b)))
        .cloned()
        .expect("an apple")
}

/// The detach motion from joint position `at`: twist the wrist 45 degrees, then move back to
/// `home` with the twist kept; returns the world's events of the pull.
pub fn twist_and_pull_home(
    robot: &mut SimRobot,
    arm: ArmId,
    at: [f64; 4],
    home: [f64; 4],
) -> Vec<WorldEvent> {
    let mut twisted = at;
    twisted[3] = std::f64::consts::FRAC_PI_4;
    move_to(robot, arm, twisted, 0.3);
    let mut home = home;
    home[3] = twisted[3];
    move_to(robot, arm, home, 2.0)
}
