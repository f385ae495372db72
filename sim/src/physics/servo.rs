//! First-order servo dynamics of one arm's four joints (Teknic integrated servos,
//! [dual-arm sec. 2.2]).
//!
//! Each joint follows its command with a first-order lag of time constant `tau`:
//! - position command `p*`: `p(t + dt) = p* + (p(t) - p*) exp(-dt / tau)`, the implied velocity
//!   limited to the joint's rate limit;
//! - velocity command `v*`: `v(t + dt) = v* + (v(t) - v*) exp(-dt / tau)`, then `p += v dt`.
//!
//! Positions are clamped to the joint limits (the velocity drops to zero at a limit). The limits
//! are the robot model's: position ranges as [`JointLimits`] and rate limits as a
//! [`JointVelocity`] of magnitudes, the two fields of
//! [`harvest_robot_model::params::ArmParams`] (Table 1). Joint units are metres for the
//! prismatic joint and radians for the revolute ones, in `[D, theta, phi, twist]` order.

use harvest_robot_model::joint::{Joint, JointPosition, JointVelocity};
use harvest_robot_model::params::JointLimits;

/// Joints of one arm: `[D m, theta rad, phi rad, twist rad]`.
pub const JOINTS: usize = Joint::ALL.len();

/// What one joint's servo drive is told to do for the next step (not the arm controller's
/// rate command for all four servos, `harvest_arm::controller::JointCommand`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ServoCommand {
    /// Go to this position (m or rad).
    Position(f64),
    /// Move at this velocity (m/s or rad/s).
    Velocity(f64),
}

/// Why a servo model refused a request.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ServoError {
    /// A joint's limits are empty, inverted or not finite.
    #[error(
        "joint {joint}: invalid limits [{min_position}, {max_position}], rate {max_velocity} \
         (need min < max and a rate limit > 0)"
    )]
    InvalidLimits {
        /// The joint.
        joint: Joint,
        /// Lower travel limit (m or rad).
        min_position: f64,
        /// Upper travel limit (m or rad).
        max_position: f64,
        /// Rate limit (m/s or rad/s).
        max_velocity: f64,
    },
    /// The time constant is not a positive finite number of seconds.
    #[error("servo time constant {time_constant_s} s must be > 0")]
    InvalidTimeConstant { time_constant_s: f64 },
    /// The step length is not a positive finite number of seconds.
    #[error("servo step dt_s = {dt_s} must be > 0 and finite")]
    InvalidTimeStep { dt_s: f64 },
    /// A command value is NaN or infinite.
    #[error("joint {joint}: command {command:?} is not finite")]
    NonFiniteCommand { joint: Joint, command: ServoCommand },
    /// A restored joint position or rate is NaN or infinite.
    #[error("joint {joint}: restored position {position} / rate {velocity} is not finite")]
    NonFiniteRestore {
        joint: Joint,
        position: f64,
        velocity: f64,
    },
}

/// The four joints of one arm driven by first-order servos.
#[derive(Debug, Clone, PartialEq)]
pub struct ServoModel {
    position_limits: JointLimits,
    /// Rate limit magnitude of each joint, `[D, theta, phi, twist]`.
    max_velocity: [f64; JOINTS],
    time_constant_s: f64,
    position: [f64; JOINTS],
    velocity: [f64; JOINTS],
}

impl ServoModel {
    /// Joints at rest at `initial_position` (clamped to `position_limits`), each rate limited
    /// to the magnitude in `rate_limits`.
    pub fn new(
        position_limits: JointLimits,
        rate_limits: JointVelocity,
        time_constant_s: f64,
        initial_position: JointPosition,
    ) -> Result<Self, ServoError> {
        let (lo, hi) = (
            position_limits.min.to_array(),
            position_limits.max.to_array(),
        );
        let max_velocity = rate_limits.to_array();
        for joint in Joint::ALL {
            let k = joint.index();
            let valid = lo[k] < hi[k]
                && lo[k].is_finite()
                && hi[k].is_finite()
                && max_velocity[k] > 0.0
                && max_velocity[k].is_finite();
            if !valid {
                return Err(ServoError::InvalidLimits {
                    joint,
                    min_position: lo[k],
                    max_position: hi[k],
                    max_velocity: max_velocity[k],
                });
            }
        }
        if !(time_constant_s > 0.0 && time_constant_s.is_finite()) {
            return Err(ServoError::InvalidTimeConstant { time_constant_s });
        }
        let initial = initial_position.to_array();
        let position = std::array::from_fn(|k| initial[k].clamp(lo[k], hi[k]));
        Ok(Self {
            position_limits,
            max_velocity,
            time_constant_s,
            position,
            velocity: [0.0; JOINTS],
        })
    }

    /// Advances every joint by `dt_s` under its command.
    pub fn step(&mut self, dt_s: f64, commands: &[ServoCommand; JOINTS]) -> Result<(), ServoError> {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return Err(ServoError::InvalidTimeStep { dt_s });
        }
        for (joint, command) in Joint::ALL.into_iter().zip(commands) {
            let value = match command {
                ServoCommand::Position(p) | ServoCommand::Velocity(p) => *p,
            };
            if !value.is_finite() {
                return Err(ServoError::NonFiniteCommand {
                    joint,
                    command: *command,
                });
            }
        }
        let decay = (-dt_s / self.time_constant_s).exp();
        let (lo, hi) = (
            self.position_limits.min.to_array(),
            self.position_limits.max.to_array(),
        );
        for (joint, command) in commands.iter().enumerate() {
            let (min_position, max_position) = (lo[joint], hi[joint]);
            let max_velocity = self.max_velocity[joint];
            let position = self.position[joint];
            let velocity = match *command {
                ServoCommand::Position(target) => {
                    let target = target.clamp(min_position, max_position);
                    let next = target + (position - target) * decay;
                    (next - position) / dt_s
                }
                ServoCommand::Velocity(target) => {
                    let target = target.clamp(-max_velocity, max_velocity);
                    target + (self.velocity[joint] - target) * decay
                }
            }
            .clamp(-max_velocity, max_velocity);
            let next = position + velocity * dt_s;
            let clamped = next.clamp(min_position, max_position);
            self.position[joint] = clamped;
            self.velocity[joint] = if clamped == next { velocity } else { 0.0 };
        }
        Ok(())
    }

    /// Joint positions `[D, theta, phi, twist]` (m or rad).
    pub fn positions(&self) -> [f64; JOINTS] {
        self.position
    }

    /// Joint velocities `[D, theta, phi, twist]` (m/s or rad/s).
    pub fn velocities(&self) -> [f64; JOINTS] {
        self.velocity
    }

    /// Puts the joints where a saved state had them (a restart of the simulator): positions
    /// clamped to the limits, rates to the rate limits; non-finite values are refused.
    pub fn restore(
        &mut self,
        position: [f64; JOINTS],
        velocity: [f64; JOINTS],
    ) -> Result<(), ServoError> {
        for joint in Joint::ALL {
            let k = joint.index();
            if !(position[k].is_finite() && velocity[k].is_finite()) {
                return Err(ServoError::NonFiniteRestore {
                    joint,
                    position: position[k],
                    velocity: velocity[k],
                });
            }
        }
        let (lo, hi) = (
            self.position_limits.min.to_array(),
            self.position_limits.max.to_array(),
        );
        self.position = std::array::from_fn(|k| position[k].clamp(lo[k], hi[k]));
        self.velocity =
            std::array::from_fn(|k| velocity[k].clamp(-self.max_velocity[k], self.max_velocity[k]));
        Ok(())
    }

    /// The joint position ranges the servos stop at.
    pub fn position_limits(&self) -> &JointLimits {
        &self.position_limits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every joint in `[-1, 1]` with a rate limit of `max_velocity`.
    fn limits(max_velocity: f64) -> (JointLimits, JointVelocity) {
        (
            JointLimits {
                min: JointPosition::from_array([-1.0; JOINTS]),
                max: JointPosition::from_array([1.0; JOINTS]),
            },
            JointVelocity::from_array([max_velocity; JOINTS]),
        )
    }

    fn servo(max_velocity: f64, tau: f64) -> ServoModel {
        let (position_limits, rate_limits) = limits(max_velocity);
        ServoModel::new(position_limits, rate_limits, tau, JointPosition::default()).expect("servo")
    }

    #[test]
    fn position_step_response_is_first_order() {
        let tau = 0.05;
        let mut servo = servo(100.0, tau);
        let dt = 0.001;
        let steps = (tau / dt).round() as usize;
        for _ in 0..steps {
            servo
                .step(dt, &[ServoCommand::Position(0.5); JOINTS])
                .expect("step");
        }
        // After one time constant: 1 - 1/e of the step.
        let expected = 0.5 * (1.0 - (-1.0f64).exp());
        for position in servo.positions() {
            assert!(
                (position - expected).abs() < 1e-9,
                "{:?}",
                servo.positions()
            );
        }
    }

    #[test]
    fn velocity_is_limited_and_positions_stop_at_limits() {
        let mut servo = servo(0.2, 0.01);
        for _ in 0..100 {
            servo
                .step(0.01, &[ServoCommand::Position(0.9); JOINTS])
                .expect("step");
        }
        // One second at 0.2 m/s at most.
        assert!(servo.positions()[0] <= 0.2 + 1e-12);
        assert!((servo.velocities()[0] - 0.2).abs() < 1e-9);
        for _ in 0..2000 {
            servo
                .step(0.01, &[ServoCommand::Velocity(5.0); JOINTS])
                .expect("step");
        }
        assert_eq!(servo.positions(), [1.0; JOINTS]);
        assert_eq!(servo.velocities(), [0.0; JOINTS]);
    }

    #[test]
    fn table_1_limits_are_the_servo_limits() {
        let params = harvest_robot_model::params::ArmParams::arm1();
        let mut servo = ServoModel::new(
            params.position_limits,
            params.rate_limits,
            0.02,
            params.home,
        )
        .expect("servo");
        for _ in 0..5000 {
            servo
                .step(0.01, &[ServoCommand::Velocity(f64::MAX); JOINTS])
                .expect("step");
        }
        assert_eq!(servo.positions(), params.position_limits.max.to_array());
        assert_eq!(servo.position_limits(), &params.position_limits);
    }

    #[test]
    fn bad_inputs_are_refused() {
        let (position_limits, rate_limits) = limits(100.0);
        let home = JointPosition::default();
        assert!(ServoModel::new(position_limits, rate_limits, 0.0, home).is_err());
        let mut inverted = position_limits;
        inverted.min.phi_rad = 1.0;
        inverted.max.phi_rad = -1.0;
        assert!(matches!(
            ServoModel::new(inverted, rate_limits, 0.1, home),
            Err(ServoError::InvalidLimits {
                joint: Joint::Yaw,
                ..
            })
        ));
        let mut no_rate = rate_limits;
        no_rate.twist_rad_per_s = 0.0;
        assert!(matches!(
            ServoModel::new(position_limits, no_rate, 0.1, home),
            Err(ServoError::InvalidLimits {
                joint: Joint::Twist,
                ..
            })
        ));
        let mut servo = ServoModel::new(position_limits, rate_limits, 0.1, home).expect("servo");
        assert!(
            servo
                .step(0.0, &[ServoCommand::Position(0.0); JOINTS])
                .is_err()
        );
        let mut commands = [ServoCommand::Velocity(0.0); JOINTS];
        commands[1] = ServoCommand::Velocity(f64::NAN);
        assert!(matches!(
            servo.step(0.01, &commands),
            Err(ServoError::NonFiniteCommand {
                joint: Joint::Pitch,
                ..
            })
        ));
        assert_eq!(servo.positions(), [0.0; JOINTS]);
    }
}
