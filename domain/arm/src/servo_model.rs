//! First-order servo plant of one arm, used to verify the tracking controller and the picking
//! cycle (and usable by a simulator). [dual-arm sec. 3.2.3] treats the Teknic servos as
//! first-order velocity inputs; we model each joint rate as a first-order lag of the commanded
//! rate, `tau v_dot = u - v`, plus an additive rate disturbance `d` (load, friction, servo
//! mismatch), integrated to position: `q_dot = v + d`. Positions stop at the joint limits
//! (mechanical end stops).

use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::params::JointLimits;

/// Simulated servos of the four joints.
#[derive(Debug, Clone, PartialEq)]
pub struct FirstOrderServo {
    /// Velocity-loop time constant, s.
    pub time_constant_s: f64,
    /// Current joint positions.
    pub position: JointPosition,
    /// Current joint rates (without the disturbance).
    pub velocity: JointVelocity,
    limits: JointLimits,
}

impl FirstOrderServo {
    /// Servos at rest at `initial`, with end stops at `limits`.
    pub fn new(limits: JointLimits, time_constant_s: f64, initial: JointPosition) -> Self {
        Self {
            time_constant_s,
            position: initial,
            velocity: JointVelocity::ZERO,
            limits,
        }
    }

    /// Advances the plant by `dt_s` under the rate `command` and rate `disturbance`. The lag is
    /// discretised exactly for a command held over the step.
    pub fn step(&mut self, command: &JointVelocity, disturbance: &JointVelocity, dt_s: f64) {
        if dt_s.is_nan() || dt_s <= 0.0 {
            return;
        }
        let alpha = if self.time_constant_s > 0.0 {
            1.0 - (-dt_s / self.time_constant_s).exp()
        } else {
            1.0
        };
        let u = command.to_array();
        let d = disturbance.to_array();
        let mut v = self.velocity.to_array();
        let mut q = self.position.to_array();
        let (lo, hi) = (self.limits.min.to_array(), self.limits.max.to_array());
        for i in 0..4 {
            v[i] += (u[i] - v[i]) * alpha;
            let next = q[i] + (v[i] + d[i]) * dt_s;
            q[i] = next.clamp(lo[i], hi[i]);
            if q[i] != next {
                v[i] = 0.0;
            }
        }
        self.velocity = JointVelocity::from_array(v);
        self.position = JointPosition::from_array(q);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_robot_model::params::ArmParams;

    #[test]
    fn step_response_follows_the_time_constant() {
        let p = ArmParams::arm1();
        let mut s = FirstOrderServo::new(p.position_limits, 0.05, p.home);
        let u = JointVelocity::from_array([0.1, 0.0, 0.0, 0.0]);
        for _ in 0..50 {
            s.step(&u, &JointVelocity::ZERO, 0.001);
        }
        // After one time constant the rate reaches 1 - 1/e of the command.
        let expected = 0.1 * (1.0 - (-1.0f64).exp());
        assert!((s.velocity.d_m_per_s - expected).abs() < 1e-9);
    }

    #[test]
    fn end_stops_hold_the_limits() {
        let p = ArmParams::arm1();
        let mut s = FirstOrderServo::new(p.position_limits, 0.01, p.home);
        let u = JointVelocity::from_array([1.0, -1.0, 1.0, 10.0]);
        for _ in 0..5000 {
            s.step(&u, &JointVelocity::ZERO, 0.001);
        }
        assert_eq!(s.position.d_m, p.position_limits.max.d_m);
        assert_eq!(s.position.theta_rad, p.position_limits.min.theta_rad);
        assert_eq!(s.position.phi_rad, p.position_limits.max.phi_rad);
        assert_eq!(s.position.twist_rad, p.position_limits.max.twist_rad);
    }
}
