//! The simulated robot as one steppable object: the orchard [`World`] (apples, leaves, vacuum and
//! contact physics), the servos of both tube arms and the valve board, advanced together on one
//! simulated clock. The `sim` process serves the hardware channels from it; the in-process
//! harvesting evaluation drives it directly.
//!
//! Per step (split into sub-steps of at most [`SimRobotConfig::max_substep_s`]):
//! 1. each arm's servo drive turns its latest set-point into a joint-rate command (below) and the
//!    first-order [`ServoModel`] integrates it ([dual-arm sec. 3.2.3] treats the Teknic servos
//!    as first-order rate inputs);
//! 2. the end-effector positions follow from the joints by forward kinematics, eq. 1 of paper
//!    003, with each arm's Table 1 parameters ([`harvest_robot_model::params::ArmParams`]); the twist
//!    joint is the cup rotation;
//! 3. the valve commands and end-effector poses go into [`World::step`], which moves the valve
//!    gates, the three pressures and the apples and reports [`WorldEvent`]s.
//!
//! Servo drive. A set-point is a joint position valid at the time it was received plus a
//! feed-forward joint rate. Between set-points the drive extrapolates the reference
//! `r(t) = p_set + v_ff (t - t_set)` (clamped to the joint limits) and commands the rate
//! `v = v_ff + k_pos (r(t) - q(t))`: a position loop with velocity feed-forward, as industrial
//! drives do when streamed at 200 Hz. With no set-point for [`SimRobotConfig::setpoint_timeout_s`]
//! (or after [`SimRobot::hold`]) the drive brakes: rate command zero.
//!
//! Valve readings follow the valve board's two-bit report: `open[i]` is the commanded position,
//! `in_transit[i]` is true while the gate has not reached that end stop yet (the gates take
//! `vacuum.valve_travel_time_s` end to end).

use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::kinematics::forward;
use harvest_robot_model::params::ArmParams;

use crate::orchard::{OrchardError, World};
use crate::physics::servo::{ServoCommand, ServoError, ServoModel};
use crate::physics::vacuum::VacuumPlantState;
use crate::physics::{ArmId, StepError, StepInputs, WorldEvent};
use crate::scenario::Scenario;

/// Joints per arm: `[D m, theta rad, phi rad, twist rad]`.
pub const ARM_JOINTS: usize = crate::physics::servo::JOINTS;

/// Valves on the valve board (1-2 serve arm 1, 3-4 serve arm 2).
pub const VALVES: usize = 4;

/// Tunables of the simulated drives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimRobotConfig {
    /// Time constant of each joint's rate loop, s (choice: 20 ms, the servo lag the arm crate's
    /// controller was verified against).
    pub servo_time_constant_s: f64,
    /// Position-loop gain of the drive, 1/s (choice: 20/s, damping ratio 0.79 with the 20 ms
    /// rate loop).
    pub position_gain_per_s: f64,
    /// A drive that receives no set-point for this long brakes, s (choice: 50 ms = 10 periods
    /// of the 200 Hz control loop; the trait contract says commands stop => hold).
    pub setpoint_timeout_s: f64,
    /// Longest internal integration step, s (1 ms: five sub-steps per 200 Hz period).
    pub max_substep_s: f64,
}

impl Default for SimRobotConfig {
    fn default() -> Self {
        Self {
            servo_time_constant_s: 0.02,
            position_gain_per_s: 20.0,
            setpoint_timeout_s: 0.05,
            max_substep_s: 0.001,
        }
    }
}

/// Why the simulated robot refused a request or a step.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimRobotError {
    /// The orchard could not be generated from the scenario.
    #[error("generating the simulated orchard: {0}")]
    Orchard(String),
    /// A servo model refused its limits or a command.
    #[error("{arm:?} servos: {source}")]
    Servo {
        /// Which arm.
        arm: ArmId,
        /// The servo model's error.
        source: ServoError,
    },
    /// The world refused the step.
    #[error(transparent)]
    World(#[from] StepError),
    /// The step length is not a positive finite number of seconds.
    #[error("robot step dt_s = {dt_s} must be > 0 and finite")]
    InvalidTimeStep {
        /// The refused step, s.
        dt_s: f64,
    },
    /// A configuration value is out of range.
    #[error("sim robot config `{field}` = {value} must be > 0 and finite")]
    InvalidConfig {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A set-point is not finite or outside the joint's limits; nothing was applied.
    #[error(
        "{arm:?} joint {joint}: set-point position {position} / velocity {velocity} not finite \
         or position outside [{min}, {max}]"
    )]
    InvalidSetpoint {
        /// Which arm.
        arm: ArmId,
        /// Joint index `[D, theta, phi, twist]`.
        joint: usize,
        /// Commanded position (m or rad).
        position: f64,
        /// Feed-forward velocity (m/s or rad/s).
        velocity: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
}

impl From<OrchardError> for SimRobotError {
    fn from(error: OrchardError) -> Self {
        SimRobotError::Orchard(error.to_string())
    }
}

/// What one arm's drives are doing.
#[derive(Debug, Clone, Copy, PartialEq)]
enum DriveOrder {
    /// Brake (rate command zero).
    Hold,
    /// Track `position` (valid at `since_ns`) with feed-forward `velocity`.
    Track {
        position: [f64; ARM_JOINTS],
        velocity: [f64; ARM_JOINTS],
        since_ns: u64,
    },
}

#[derive(Debug, Clone)]
struct SimArm {
    params: ArmParams,
    servo: ServoModel,
    order: DriveOrder,
}

impl SimArm {
    fn new(arm: ArmId, params: ArmParams, config: &SimRobotConfig) -> Result<Self, SimRobotError> {
        let servo = ServoModel::new(
            params.position_limits,
            params.rate_limits,
            config.servo_time_constant_s,
            params.home,
        )
        .map_err(|source| SimRobotError::Servo { arm, source })?;
        Ok(Self {
            params,
            servo,
            order: DriveOrder::Hold,
        })
    }

    fn joints(&self) -> JointPosition {
        JointPosition::from_array(self.servo.positions())
    }

    fn end_effector_m(&self) -> [f64; 3] {
        forward(&self.params.links, &self.joints())
    }

    /// The drive's rate commands at `now_ns` (see the module documentation).
    fn commands(&mut self, now_ns: u64, config: &SimRobotConfig) -> [ServoCommand; ARM_JOINTS] {
        let DriveOrder::Track {
            position,
            velocity,
            since_ns,
        } = self.order
        else {
            return [ServoCommand::Velocity(0.0); ARM_JOINTS];
        };
        let elapsed_s = now_ns.saturating_sub(since_ns) as f64 * 1e-9;
        if elapsed_s > config.setpoint_timeout_s {
            tracing::trace!(arm = ?self.params.arm, elapsed_s, "set-point timeout: braking");
            self.order = DriveOrder::Hold;
            return [ServoCommand::Velocity(0.0); ARM_JOINTS];
        }
        let q = self.servo.positions();
        let limits = self.servo.position_limits();
        let (lo, hi) = (limits.min.to_array(), limits.max.to_array());
        std::array::from_fn(|j| {
            let reference = (position[j] + velocity[j] * elapsed_s).clamp(lo[j], hi[j]);
            ServoCommand::Velocity(velocity[j] + config.position_gain_per_s * (reference - q[j]))
        })
    }
}

/// The simulated robot: world, two arms' servos, valve board, one clock.
#[derive(Debug, Clone)]
pub struct SimRobot {
    world: World,
    arms: [SimArm; 2],
    valves_open: [bool; VALVES],
    time_ns: u64,
    config: SimRobotConfig,
}

impl SimRobot {
    /// The robot in the world of `scenario` generated from `seed`, both arms at rest at their
    /// home pose, every inlet valve closed and every vent open, time zero.
    pub fn new(scenario: &Scenario, seed: u64) -> Result<Self, SimRobotError> {
        Self::with_config(scenario, seed, SimRobotConfig::default())
    }

    /// As [`SimRobot::new`] with explicit drive settings.
    pub fn with_config(
        scenario: &Scenario,
        seed: u64,
        config: SimRobotConfig,
    ) -> Result<Self, SimRobotError> {
        Self::from_world(World::generate(scenario, seed)?, config)
    }

    /// The robot in an existing world (a row's, or one restored from a state file), arms at
    /// home, valves as in [`SimRobot::new`], time zero.
    pub fn from_world(world: World, config: SimRobotConfig) -> Result<Self, SimRobotError> {
        for (field, value) in [
            ("servo_time_constant_s", config.servo_time_constant_s),
            ("position_gain_per_s", config.position_gain_per_s),
            ("setpoint_timeout_s", config.setpoint_timeout_s),
            ("max_substep_s", config.max_substep_s),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(SimRobotError::InvalidConfig { field, value });
            }
        }
        let arms = [
            SimArm::new(ArmId::Arm1, ArmParams::arm1(), &config)?,
            SimArm::new(ArmId::Arm2, ArmParams::arm2(), &config)?,
        ];
        Ok(Self {
            world,
            arms,
            valves_open: StepInputs::valves_for_arms([false, false]),
            time_ns: 0,
            config,
        })
    }

    /// Advances the whole robot by `dt_s` and returns what happened to the apples.
    pub fn step(&mut self, dt_s: f64) -> Result<Vec<WorldEvent>, SimRobotError> {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return Err(SimRobotError::InvalidTimeStep { dt_s });
        }
        let total_ns = (dt_s * 1e9).round().max(1.0) as u64;
        let max_sub_ns = ((self.config.max_substep_s * 1e9).round() as u64).max(1);
        let substeps = total_ns.div_ceil(max_sub_ns);
        let mut events = Vec::new();
        let mut done_ns = 0;
        for k in 1..=substeps {
            let until_ns = total_ns * k / substeps;
            let sub_ns = until_ns - done_ns;
            done_ns = until_ns;
            let sub_s = sub_ns as f64 * 1e-9;
            for (index, arm) in self.arms.iter_mut().enumerate() {
                let commands = arm.commands(self.time_ns, &self.config);
                arm.servo
                    .step(sub_s, &commands)
                    .map_err(|source| SimRobotError::Servo {
                        arm: ArmId::ALL[index],
                        source,
                    })?;
            }
            let inputs = StepInputs {
                end_effector_in_robot_m: [
                    self.arms[0].end_effector_m(),
                    self.arms[1].end_effector_m(),
                ],
                end_effector_twist_rad: [
                    self.arms[0].servo.positions()[3],
                    self.arms[1].servo.positions()[3],
                ],
                valve_open: self.valves_open,
            };
            events.extend(self.world.step(sub_s, &inputs)?);
            self.time_ns += sub_ns;
        }
        Ok(events)
    }

    /// Streams a set-point to `arm`'s drives: joint positions `[D m, theta rad, phi rad, twist
    /// rad]` valid now and feed-forward rates. Refused (nothing applied) when a value is not
    /// finite or a position lies outside the arm's joint limits (Table 1).
    pub fn set_servo_setpoint(
        &mut self,
        arm: ArmId,
        position: [f64; ARM_JOINTS],
        velocity: [f64; ARM_JOINTS],
    ) -> Result<(), SimRobotError> {
        let sim_arm = &mut self.arms[arm.index()];
        let limits = sim_arm.servo.position_limits();
        let (lo, hi) = (limits.min.to_array(), limits.max.to_array());
        for j in 0..ARM_JOINTS {
            let (min, max) = (lo[j], hi[j]);
            let ok = position[j].is_finite()
                && velocity[j].is_finite()
                && (min..=max).contains(&position[j]);
            if !ok {
                return Err(SimRobotError::InvalidSetpoint {
                    arm,
                    joint: j,
                    position: position[j],
                    velocity: velocity[j],
                    min,
                    max,
                });
            }
        }
        sim_arm.order = DriveOrder::Track {
            position,
            velocity,
            since_ns: self.time_ns,
        };
        Ok(())
    }

    /// Brakes `arm`'s drives: rate command zero until the next set-point.
    pub fn hold(&mut self, arm: ArmId) {
        self.arms[arm.index()].order = DriveOrder::Hold;
    }

    /// True while `arm`'s drives are braking (after [`SimRobot::hold`] or a set-point timeout).
    pub fn is_holding(&self, arm: ArmId) -> bool {
        self.arms[arm.index()].order == DriveOrder::Hold
    }

    /// Encoder readings of `arm`: joint positions and rates `[D, theta, phi, twist]`.
    pub fn encoders(&self, arm: ArmId) -> ([f64; ARM_JOINTS], [f64; ARM_JOINTS]) {
        let servo = &self.arms[arm.index()].servo;
        (servo.positions(), servo.velocities())
    }

    /// Puts `arm`'s joints where a saved state had them (a restart of the simulator), drives
    /// braking until the next set-point. Non-finite values are refused.
    pub fn restore_arm(
        &mut self,
        arm: ArmId,
        position: [f64; ARM_JOINTS],
        velocity: [f64; ARM_JOINTS],
    ) -> Result<(), SimRobotError> {
        let sim_arm = &mut self.arms[arm.index()];
        sim_arm
            .servo
            .restore(position, velocity)
            .map_err(|source| SimRobotError::Servo { arm, source })?;
        sim_arm.order = DriveOrder::Hold;
        Ok(())
    }

    /// The valves' commanded positions, 1-4 (true = open).
    pub fn valves_commanded(&self) -> [bool; VALVES] {
        self.valves_open
    }

    /// Commands valves 1-4 (true = open); the gates then move at their travel rate.
    pub fn set_valves(&mut self, open: [bool; VALVES]) {
        self.valves_open = open;
    }

    /// The valve board's readings: commanded position of each valve, whether each is still
    /// travelling to it, and the vacuum (mmH2O below atmosphere) inside arm 1, inside arm 2 and
    /// at the source.
    pub fn valve_readings(&self) -> ([bool; VALVES], [bool; VALVES], [f32; 3]) {
        let vacuum: VacuumPlantState = self.world.vacuum();
        let in_transit = std::array::from_fn(|i| {
            let end = if self.valves_open[i] { 1.0 } else { 0.0 };
            (vacuum.valve_opening[i] - end).abs() > 1e-9
        });
        let pressures = [
            vacuum.arm_mmh2o[0] as f32,
            vacuum.arm_mmh2o[1] as f32,
            vacuum.source_mmh2o as f32,
        ];
        (self.valves_open, in_transit, pressures)
    }

    /// The end-effector (cup tip) of `arm`, robot frame, m (eq. 1).
    pub fn end_effector_in_robot_m(&self, arm: ArmId) -> [f64; 3] {
        self.arms[arm.index()].end_effector_m()
    }

    /// The arm parameters the simulation uses for `arm` (Table 1).
    pub fn arm_params(&self, arm: ArmId) -> &ArmParams {
        &self.arms[arm.index()].params
    }

    /// The simulated world (ground truth; evaluation only).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world, to move the robot in it ([`World::set_robot_offset_m`]).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// Simulated time since creation, s.
    pub fn time_s(&self) -> f64 {
        self.time_ns as f64 * 1e-9
    }

    /// Simulated time since creation, ns (exact sum of the steps).
    pub fn time_ns(&self) -> u64 {
        self.time_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::orchard::AppleState;
    use crate::physics::ReleaseOutcome;
    use crate::robot_test_moves::{DT, move_to, nearest_apple, run, twist_and_pull_home};
    use harvest_robot_model::kinematics::inverse;

    fn ideal() -> SimRobot {
        SimRobot::new(&Scenario::preset("ideal").expect("ideal"), 1).expect("robot")
    }

    #[test]
    fn starts_at_home_with_the_end_effector_given_by_eq_1() {
        let robot = ideal();
        for arm in ArmId::ALL {
            let (q, v) = robot.encoders(arm);
            let params = robot.arm_params(arm);
            assert_eq!(q, params.home.to_array());
            assert_eq!(v, [0.0; 4]);
            let expected = forward(&params.links, &params.home);
            assert_eq!(robot.end_effector_in_robot_m(arm), expected);
        }
        // Table 1: arm 1 home tip at x0 + x2, y0 + y1, z0 + z1.
        let p = robot.end_effector_in_robot_m(ArmId::Arm1);
        assert!((p[0] - 1.047).abs() < 1e-12 && (p[1] - 0.110).abs() < 1e-12);
        assert!((p[2] - 0.221).abs() < 1e-12);
        assert_eq!(robot.time_ns(), 0);
    }

    #[test]
    fn time_is_the_exact_sum_of_the_steps() {
        let mut robot = ideal();
        for _ in 0..1000 {
            robot.step(DT).expect("step");
        }
        assert_eq!(robot.time_ns(), 5_000_000_000);
        robot.step(0.0025).expect("step");
        assert_eq!(robot.time_ns(), 5_002_500_000);
    }

    #[test]
    fn a_streamed_ramp_is_followed_and_hold_brakes() {
        let mut robot = ideal();
        // Extend D at 0.1 m/s for 2 s by streaming the ramp at 200 Hz.
        let (q0, _) = robot.encoders(ArmId::Arm1);
        for k in 0..400 {
            let t = k as f64 * DT;
            let mut position = q0;
            position[0] += 0.1 * t;
            robot
                .set_servo_setpoint(ArmId::Arm1, position, [0.1, 0.0, 0.0, 0.0])
                .expect("set-point");
            robot.step(DT).expect("step");
        }
        let (q, v) = robot.encoders(ArmId::Arm1);
        // The position loop removes the rate lag: within a millimetre of the ramp at 2 s.
        assert!((q[0] - (q0[0] + 0.2)).abs() < 1e-3, "{}", q[0]);
        assert!((v[0] - 0.1).abs() < 1e-3, "{}", v[0]);
        assert_eq!(q[1..], q0[1..]);
        robot.hold(ArmId::Arm1);
        run(&mut robot, 0.5);
        let (held, v) = robot.encoders(ArmId::Arm1);
        assert!(v[0].abs() < 1e-6);
        // Braking from 0.1 m/s through a 20 ms lag travels about 2 mm.
        assert!((held[0] - q[0]) > 0.0 && (held[0] - q[0]) < 0.004);
        assert!(robot.is_holding(ArmId::Arm1));
    }

    #[test]
    fn drives_brake_when_set_points_stop() {
        let mut robot = ideal();
        let (q0, _) = robot.encoders(ArmId::Arm2);
        let mut position = q0;
        position[0] += 0.001;
        robot
            .set_servo_setpoint(ArmId::Arm2, position, [0.2, 0.0, 0.0, 0.0])
            .expect("set-point");
        run(&mut robot, 1.0);
        let (q, v) = robot.encoders(ArmId::Arm2);
        assert!(robot.is_holding(ArmId::Arm2));
        assert!(v[0].abs() < 1e-9, "{}", v[0]);
        // 50 ms of streaming at most 0.2 m/s, plus the braking lag.
        assert!(q[0] - q0[0] < 0.02, "{}", q[0]);
    }

    #[test]
    fn bad_set_points_are_refused_and_change_nothing() {
        let mut robot = ideal();
        let limits = robot.arm_params(ArmId::Arm1).position_limits;
        let mut position = robot.arm_params(ArmId::Arm1).home.to_array();
        position[0] = limits.max.d_m + 0.01;
        let error = robot
            .set_servo_setpoint(ArmId::Arm1, position, [0.0; 4])
            .expect_err("outside limits");
        assert!(matches!(
            error,
            SimRobotError::InvalidSetpoint {
                arm: ArmId::Arm1,
                joint: 0,
                ..
            }
        ));
        let home = robot.arm_params(ArmId::Arm1).home.to_array();
        assert!(
            robot
                .set_servo_setpoint(ArmId::Arm1, home, [0.0, f64::NAN, 0.0, 0.0])
                .is_err()
        );
        assert!(robot.is_holding(ArmId::Arm1));
        assert!(robot.step(0.0).is_err());
        assert!(robot.step(f64::NAN).is_err());
    }

    #[test]
    fn valves_report_transit_then_the_end_stop_and_pressures_respond() {
        let mut robot = ideal();
        let (open, transit, p) = robot.valve_readings();
        assert_eq!(open, [false, true, false, true]);
        assert_eq!(transit, [false; 4]);
        assert!(p[0].abs() < 1.0 && p[2] > 2000.0);
        robot.set_valves(StepInputs::valves_for_arms([true, false]));
        robot.step(DT).expect("step");
        let (open, transit, _) = robot.valve_readings();
        assert_eq!(open, [true, false, false, true]);
        assert_eq!(transit, [true, true, false, false]);
        let travel = robot.world().scenario().vacuum.valve_travel_time_s;
        run(&mut robot, travel + 0.5);
        let (_, transit, p) = robot.valve_readings();
        assert_eq!(transit, [false; 4]);
        // Arm 1 open to the air through its cup: a fraction of the source.
        assert!(p[0] > 100.0 && p[0] < 0.8 * p[2], "{p:?}");
        assert!(p[1].abs() < 1.0);
    }

    /// Drive arm 1's cup onto the nearest apple with set-points, open its valve, pull back to
    /// home, close: the apple lands on the dropping module.
    #[test]
    fn a_scripted_pick_harvests_an_apple() {
        let mut robot = ideal();
        let params = *robot.arm_params(ArmId::Arm1);
        let apple = nearest_apple(&robot, ArmId::Arm1);
        let c = apple.center_in_robot_m;
        let pick = [c[0] - apple.radius_m, c[1], c[2]];
        let q = inverse(&params, pick).expect("reachable").to_array();
        let events = move_to(&mut robot, ArmId::Arm1, q, 2.0);
        assert!(events.is_empty(), "{events:?}");
        let tip = robot.end_effector_in_robot_m(ArmId::Arm1);
        assert!((0..3).all(|i| (tip[i] - pick[i]).abs() < 0.002), "{tip:?}");
        robot.set_valves(StepInputs::valves_for_arms([true, false]));
        let events = run(&mut robot, 1.0);
        assert_eq!(
            events,
            vec![WorldEvent::Attached {
                arm: ArmId::Arm1,
                apple: apple.id
            }]
        );
        let events = twist_and_pull_home(&mut robot, ArmId::Arm1, q, params.home.to_array());
        assert_eq!(
            events,
            vec![WorldEvent::Detached {
                arm: ArmId::Arm1,
                apple: apple.id
            }]
        );
        robot.set_valves(StepInputs::valves_for_arms([false, false]));
        let events = run(&mut robot, 1.5);
        assert_eq!(
            events,
            vec![WorldEvent::Released {
                arm: ArmId::Arm1,
                apple: apple.id,
                outcome: ReleaseOutcome::Harvested
            }]
        );
        let state = robot.world().apples()[0..]
            .iter()
            .find(|a| a.id == apple.id)
            .map(|a| a.state);
        assert_eq!(state, Some(AppleState::Harvested));
    }

    #[test]
    fn same_seed_same_run() {
        let trace = |seed: u64| {
            let mut scenario = Scenario::preset("ideal").expect("ideal");
            scenario.failures.seal_failure = 0.5;
            let mut robot = SimRobot::new(&scenario, seed).expect("robot");
            robot.set_valves(StepInputs::valves_for_arms([true, true]));
            let mut all = run(&mut robot, 0.5);
            all.extend(move_to(&mut robot, ArmId::Arm2, [0.2, 0.1, 0.05, 0.0], 1.0));
            (all, robot.encoders(ArmId::Arm2), robot.valve_readings())
        };
        assert_eq!(trace(4), trace(4));
    }
}
