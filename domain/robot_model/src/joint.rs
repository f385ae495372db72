//! Joint-space vectors of one 4-DOF tube arm ([dual-arm sec. 2.2]): the prismatic joint `D`
//! along the robot x axis, the pitch joint `theta`, the yaw joint `phi` and the end-effector
//! twist `psi` that rotates the soft cup about the tube axis. The twist does not move the
//! end-effector position, so eq. 1 and eq. 2 only involve the first three joints.

use std::fmt;

use serde::{Deserialize, Serialize};

/// One joint of the arm, in the order used by every joint-space array of this crate
/// (`[D, theta, phi, twist]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Joint {
    /// Prismatic joint `D` (metres), translates the whole tube along the robot x axis.
    Prismatic,
    /// Revolute joint `theta` (radians), pitches the tube up (positive) or down.
    Pitch,
    /// Revolute joint `phi` (radians), yaws the tube; positive moves the tip toward -y.
    Yaw,
    /// End-effector rotation `psi` (radians) about the tube axis, used to twist the apple off.
    Twist,
}

impl Joint {
    /// All joints in array order.
    pub const ALL: [Joint; 4] = [Joint::Prismatic, Joint::Pitch, Joint::Yaw, Joint::Twist];

    /// Index of this joint in `[D, theta, phi, twist]` arrays.
    pub fn index(self) -> usize {
        match self {
            Joint::Prismatic => 0,
            Joint::Pitch => 1,
            Joint::Yaw => 2,
            Joint::Twist => 3,
        }
    }
}

impl fmt::Display for Joint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            Joint::Prismatic => "D (prismatic, m)",
            Joint::Pitch => "theta (pitch, rad)",
            Joint::Yaw => "phi (yaw, rad)",
            Joint::Twist => "twist (end-effector rotation, rad)",
        };
        f.write_str(name)
    }
}

/// Joint positions `q = [D, theta, phi, twist]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointPosition {
    /// Prismatic extension `D` in metres.
    pub d_m: f64,
    /// Pitch angle `theta` in radians.
    pub theta_rad: f64,
    /// Yaw angle `phi` in radians.
    pub phi_rad: f64,
    /// End-effector twist angle in radians.
    pub twist_rad: f64,
}

impl JointPosition {
    /// Builds from a `[D, theta, phi, twist]` array (m, rad, rad, rad).
    pub fn from_array(q: [f64; 4]) -> Self {
        Self {
            d_m: q[0],
            theta_rad: q[1],
            phi_rad: q[2],
            twist_rad: q[3],
        }
    }

    /// The `[D, theta, phi, twist]` array (m, rad, rad, rad).
    pub fn to_array(&self) -> [f64; 4] {
        [self.d_m, self.theta_rad, self.phi_rad, self.twist_rad]
    }

    /// The value of one joint (m or rad).
    pub fn get(&self, joint: Joint) -> f64 {
        self.to_array()[joint.index()]
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|v| v.is_finite())
    }

    /// Same joints with a different twist angle.
    pub fn with_twist(&self, twist_rad: f64) -> Self {
        Self { twist_rad, ..*self }
    }
}

/// Joint rates `q_dot = [D_dot, theta_dot, phi_dot, twist_dot]`; the servos of the arm are
/// commanded in this space (section 3.2.3: first-order velocity inputs).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointVelocity {
    /// Prismatic rate in metres per second.
    pub d_m_per_s: f64,
    /// Pitch rate in radians per second.
    pub theta_rad_per_s: f64,
    /// Yaw rate in radians per second.
    pub phi_rad_per_s: f64,
    /// Twist rate in radians per second.
    pub twist_rad_per_s: f64,
}

impl JointVelocity {
    /// All rates zero: the servos hold position.
    pub const ZERO: Self = Self {
        d_m_per_s: 0.0,
        theta_rad_per_s: 0.0,
        phi_rad_per_s: 0.0,
        twist_rad_per_s: 0.0,
    };

    /// Builds from a `[D, theta, phi, twist]` rate array (m/s, rad/s, rad/s, rad/s).
    pub fn from_array(v: [f64; 4]) -> Self {
        Self {
            d_m_per_s: v[0],
            theta_rad_per_s: v[1],
            phi_rad_per_s: v[2],
            twist_rad_per_s: v[3],
        }
    }

    /// The `[D, theta, phi, twist]` rate array (m/s, rad/s, rad/s, rad/s).
    pub fn to_array(&self) -> [f64; 4] {
        [
            self.d_m_per_s,
            self.theta_rad_per_s,
            self.phi_rad_per_s,
            self.twist_rad_per_s,
        ]
    }

    /// The rate of one joint (m/s or rad/s).
    pub fn get(&self, joint: Joint) -> f64 {
        self.to_array()[joint.index()]
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|v| v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_round_trip_in_documented_order() {
        let q = JointPosition::from_array([0.1, 0.2, 0.3, 0.4]);
        assert_eq!(q.d_m, 0.1);
        assert_eq!(q.get(Joint::Pitch), 0.2);
        assert_eq!(q.get(Joint::Yaw), 0.3);
        assert_eq!(q.get(Joint::Twist), 0.4);
        assert_eq!(JointPosition::from_array(q.to_array()), q);
        let v = JointVelocity::from_array([1.0, 2.0, 3.0, 4.0]);
        assert_eq!(v.get(Joint::Prismatic), 1.0);
        assert_eq!(JointVelocity::from_array(v.to_array()), v);
        for (i, joint) in Joint::ALL.iter().enumerate() {
            assert_eq!(joint.index(), i);
        }
    }

    #[test]
    fn finiteness_checks_every_component() {
        assert!(JointPosition::default().is_finite());
        let q = JointPosition {
            twist_rad: f64::NAN,
            ..JointPosition::default()
        };
        assert!(!q.is_finite());
        let mut v = JointVelocity::ZERO;
        v.phi_rad_per_s = f64::INFINITY;
        assert!(!v.is_finite());
    }
}
