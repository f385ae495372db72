//! First-order servo dynamics of arm joints (Teknic integrated servos, paper 003 section 2.2).
//!
//! Each joint follows its command with a first-order lag of time constant `tau`:
//! - position command `p*`: `p(t + dt) = p* + (p(t) - p*) exp(-dt / tau)`, the implied velocity
//!   limited to `max_velocity`;
//! - velocity command `v*`: `v(t + dt) = v* + (v(t) - v*) exp(-dt / tau)`, then `p += v dt`.
//!
//! Positions are clamped to the joint limits (the velocity drops to zero at a limit). Joint units
//! are metres for a prismatic joint and radians for a revolute one.

/// Limits of one joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lower travel limit (m or rad).
    pub min_position: f64,
    /// Upper travel limit (m or rad).
    pub max_position: f64,
    /// Largest speed (m/s or rad/s).
    pub max_velocity: f64,
}

/// What one joint is told to do for the next step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointCommand {
    /// Go to this position (m or rad).
    Position(f64),
    /// Move at this velocity (m/s or rad/s).
    Velocity(f64),
}

/// Why a servo model refused a request.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ServoError {
    /// A joint's limits are empty, inverted or not finite.
    #[error("joint {joint}: invalid limits {limits:?} (need min < max and max_velocity > 0)")]
    InvalidLimits { joint: usize, limits: JointLimits },
    /// The time constant is not a positive finite number of seconds.
    #[error("servo time constant {time_constant_s} s must be > 0")]
    InvalidTimeConstant { time_constant_s: f64 },
    /// The step length is not a positive finite number of seconds.
    #[error("servo step dt_s = {dt_s} must be > 0 and finite")]
    InvalidTimeStep { dt_s: f64 },
    /// A command value is NaN or infinite.
    #[error("joint {joint}: command {command:?} is not finite")]
    NonFiniteCommand { joint: usize, command: JointCommand },
}

/// `N` joints driven by first-order servos.
#[derive(Debug, Clone, PartialEq)]
pub struct ServoModel<const N: usize> {
    limits: [JointLimits; N],
    time_constant_s: f64,
    position: [f64; N],
    velocity: [f64; N],
}

impl<const N: usize> ServoModel<N> {
    /// Joints at rest at `initial_position` (clamped to the limits).
    pub fn new(
        limits: [JointLimits; N],
        time_constant_s: f64,
        initial_position: [f64; N],
    ) -> Result<Self, ServoError> {
        for (joint, l) in limits.iter().enumerate() {
            let valid = l.min_position < l.max_position
                && l.min_position.is_finite()
                && l.max_position.is_finite()
                && l.max_velocity > 0.0
                && l.max_velocity.is_finite();
            if !valid {
                return Err(ServoError::InvalidLimits { joint, limits: *l });
            }
        }
        if !(time_constant_s > 0.0 && time_constant_s.is_finite()) {
            return Err(ServoError::InvalidTimeConstant { time_constant_s });
        }
        let position = std::array::from_fn(|k| {
            initial_position[k].clamp(limits[k].min_position, limits[k].max_position)
        });
        Ok(Self {
            limits,
            time_constant_s,
            position,
            velocity: [0.0; N],
        })
    }

    /// Advances every joint by `dt_s` under its command.
    pub fn step(&mut self, dt_s: f64, commands: &[JointCommand; N]) -> Result<(), ServoError> {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return Err(ServoError::InvalidTimeStep { dt_s });
        }
        for (joint, command) in commands.iter().enumerate() {
            let value = match command {
                JointCommand::Position(p) | JointCommand::Velocity(p) => *p,
            };
            if !value.is_finite() {
                return Err(ServoError::NonFiniteCommand {
                    joint,
                    command: *command,
                });
            }
        }
        let decay = (-dt_s / self.time_constant_s).exp();
        for (joint, command) in commands.iter().enumerate() {
            let limits = self.limits[joint];
            let position = self.position[joint];
            let velocity = match *command {
                JointCommand::Position(target) => {
                    let target = target.clamp(limits.min_position, limits.max_position);
                    let next = target + (position - target) * decay;
                    (next - position) / dt_s
                }
                JointCommand::Velocity(target) => {
                    let target = target.clamp(-limits.max_velocity, limits.max_velocity);
                    target + (self.velocity[joint] - target) * decay
                }
            }
            .clamp(-limits.max_velocity, limits.max_velocity);
            let next = position + velocity * dt_s;
            let clamped = next.clamp(limits.min_position, limits.max_position);
            self.position[joint] = clamped;
            self.velocity[joint] = if clamped == next { velocity } else { 0.0 };
        }
        Ok(())
    }

    /// Joint positions (m or rad).
    pub fn positions(&self) -> [f64; N] {
        self.position
    }

    /// Joint velocities (m/s or rad/s).
    pub fn velocities(&self) -> [f64; N] {
        self.velocity
    }

    pub fn limits(&self) -> &[JointLimits; N] {
        &self.limits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: JointLimits = JointLimits {
        min_position: -1.0,
        max_position: 1.0,
        max_velocity: 100.0,
    };

    #[test]
    fn position_step_response_is_first_order() {
        let tau = 0.05;
        let mut servo = ServoModel::new([LIMITS], tau, [0.0]).expect("servo");
        let dt = 0.001;
        let steps = (tau / dt).round() as usize;
        for _ in 0..steps {
            servo
                .step(dt, &[JointCommand::Position(0.5)])
                .expect("step");
        }
        // After one time constant: 1 - 1/e of the step.
        let expected = 0.5 * (1.0 - (-1.0f64).exp());
        assert!(
            (servo.positions()[0] - expected).abs() < 1e-9,
            "{:?}",
            servo.positions()
        );
    }

    #[test]
    fn velocity_is_limited_and_positions_stop_at_limits() {
        let limits = JointLimits {
            max_velocity: 0.2,
            ..LIMITS
        };
        let mut servo = ServoModel::new([limits], 0.01, [0.0]).expect("servo");
        for _ in 0..100 {
            servo
                .step(0.01, &[JointCommand::Position(0.9)])
                .expect("step");
        }
        // One second at 0.2 m/s at most.
        assert!(servo.positions()[0] <= 0.2 + 1e-12);
        assert!((servo.velocities()[0] - 0.2).abs() < 1e-9);
        for _ in 0..2000 {
            servo
                .step(0.01, &[JointCommand::Velocity(5.0)])
                .expect("step");
        }
        assert_eq!(servo.positions()[0], 1.0);
        assert_eq!(servo.velocities()[0], 0.0);
    }

    #[test]
    fn bad_inputs_are_refused() {
        assert!(ServoModel::new([LIMITS], 0.0, [0.0]).is_err());
        let inverted = JointLimits {
            min_position: 1.0,
            max_position: -1.0,
            max_velocity: 1.0,
        };
        assert!(matches!(
            ServoModel::new([inverted], 0.1, [0.0]),
            Err(ServoError::InvalidLimits { joint: 0, .. })
        ));
        let mut servo = ServoModel::new([LIMITS], 0.1, [0.0]).expect("servo");
        assert!(servo.step(0.0, &[JointCommand::Position(0.0)]).is_err());
        assert!(
            servo
                .step(0.01, &[JointCommand::Velocity(f64::NAN)])
                .is_err()
        );
        assert_eq!(servo.positions(), [0.0]);
    }
}
