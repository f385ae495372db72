//! Geometry and limits of the two tube arms: [dual-arm Table 1] (link parameters of eq. 1 and
//! joint limits) and section 2.2 (maximum end-effector speed of the Teknic servos).
//!
//! Frame. Eq. 1 expresses both arms in one frame: Table 1 gives each arm its own base offset
//! (`x0, y0, z0`) and shoulder offset (`y1`), arm 1 on the +y side (`y0 + y1 = +0.110 m`) and
//! arm 2 on the -y side (`-0.111 m`), i.e. side by side as section 2.2 describes. We therefore
//! take the eq. 1 frame to be the robot frame: x forward toward the canopy (the prismatic axis
//! and the tube direction at zero angles), y to the left, z up. The mounting pose of each arm in
//! that frame is its pure translation `(x0, y0, z0)` (no rotation); no other transform is needed.
//!
//! Values the paper does not give are documented choices, marked "choice" below: the twist joint
//! limits and rate, the per-joint rate limits, and the home (drop-off) pose.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::joint::{Joint, JointPosition, JointVelocity};

/// Maximum end-effector speed of either arm carrying a 1.5 kg payload (section 2.2), m/s.
pub const MAX_END_EFFECTOR_SPEED_M_PER_S: f64 = 0.7748;

/// Twist joint range, rad (choice: one half turn either way; Table 1 gives no twist limits).
pub const TWIST_LIMIT_RAD: f64 = std::f64::consts::PI;

/// Twist joint rate limit, rad/s (choice: one revolution per second).
pub const TWIST_RATE_LIMIT_RAD_PER_S: f64 = 2.0 * std::f64::consts::PI;

pub use harvest_ipc::ArmId;

/// Link parameters of eq. 1 (Table 1), metres, in the robot frame.
///
/// `(x0, y0, z0)`: the pitch axis position when `D = 0`; `(x1, y1, z1)`: offset from the pitch
/// axis to the yaw axis, expressed in the pitched frame; `x2`: length from the yaw axis to the
/// end-effector along the tube.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkParams {
    /// Base offset along x, m.
    pub x0_m: f64,
    /// Base offset along y, m.
    pub y0_m: f64,
    /// Base offset along z, m.
    pub z0_m: f64,
    /// Pitch-to-yaw offset along the pitched x axis, m.
    pub x1_m: f64,
    /// Pitch-to-yaw offset along y, m.
    pub y1_m: f64,
    /// Pitch-to-yaw offset along the pitched z axis, m.
    pub z1_m: f64,
    /// Tube length from the yaw axis to the end-effector, m.
    pub x2_m: f64,
}

/// Closed joint ranges `[min, max]` for `[D, theta, phi, twist]` (m, rad, rad, rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointLimits {
    /// Lower bound of each joint.
    pub min: JointPosition,
    /// Upper bound of each joint.
    pub max: JointPosition,
}

impl JointLimits {
    /// True when `q` lies inside every range (bounds included).
    pub fn contains(&self, q: &JointPosition) -> bool {
        Joint::ALL.iter().all(|&j| {
            let v = q.get(j);
            v >= self.min.get(j) && v <= self.max.get(j)
        })
    }

    /// `q` with every component clamped into its range.
    pub fn clamp(&self, q: &JointPosition) -> JointPosition {
        let (lo, hi, v) = (self.min.to_array(), self.max.to_array(), q.to_array());
        JointPosition::from_array(std::array::from_fn(|i| v[i].clamp(lo[i], hi[i])))
    }
}

/// Everything the kinematics, trajectory generator and controller need to know about one arm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmParams {
    /// Which arm these parameters describe.
    pub arm: ArmId,
    /// Eq. 1 link parameters (Table 1).
    pub links: LinkParams,
    /// Joint position limits (Table 1 for D, theta, phi; choice for the twist).
    pub position_limits: JointLimits,
    /// Magnitude limit of each joint rate (choice, see [`ArmParams::arm1`]).
    pub rate_limits: JointVelocity,
    /// Maximum end-effector speed, m/s (section 2.2).
    pub max_end_effector_speed_m_per_s: f64,
    /// Home pose above the dropping module, where apples are released (choice).
    pub home: JointPosition,
}

/// Why a parameter set is unusable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParamsError {
    /// A parameter is NaN or infinite.
    #[error("{arm}: parameter `{field}` is not finite ({value})")]
    NonFinite {
        /// Arm whose parameters are wrong.
        arm: ArmId,
        /// Name of the offending field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A length or rate that must be strictly positive is not.
    #[error("{arm}: parameter `{field}` must be > 0, got {value}")]
    NotPositive {
        /// Arm whose parameters are wrong.
        arm: ArmId,
        /// Name of the offending field.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// A joint range has `min > max`.
    #[error("{arm}: joint {joint} range is empty: min {min} > max {max}")]
    EmptyRange {
        /// Arm whose parameters are wrong.
        arm: ArmId,
        /// The joint.
        joint: Joint,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
    /// The home pose lies outside the joint limits.
    #[error("{arm}: home value {value} of joint {joint} is outside [{min}, {max}]")]
    HomeOutsideLimits {
        /// Arm whose parameters are wrong.
        arm: ArmId,
        /// The joint.
        joint: Joint,
        /// Home value.
        value: f64,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
}

impl ArmParams {
    /// Arm 1 (left, +y) from Table 1.
    ///
    /// Rate limits (choice; the paper only gives the end-effector speed): each joint alone may
    /// move the end-effector at most at the 0.7748 m/s maximum, i.e. `D_dot <= 0.7748 m/s`,
    /// `theta_dot <= 0.7748 / (x2 + z1)`, `phi_dot <= 0.7748 / x2`; twist 1 rev/s.
    /// Home (choice): all joints zero, the tube level and retracted above the dropping module.
    pub fn arm1() -> Self {
        Self::from_table(
            ArmId::Arm1,
            LinkParams {
                x0_m: 0.147,
                y0_m: 0.017,
                z0_m: 0.083,
                x1_m: 0.0,
                y1_m: 0.093,
                z1_m: 0.138,
                x2_m: 0.90,
            },
            (-17.0, 30.0),
            (-19.0, 19.0),
        )
    }

    /// Arm 2 (right, -y) from Table 1; same choices as [`ArmParams::arm1`].
    pub fn arm2() -> Self {
        Self::from_table(
            ArmId::Arm2,
            LinkParams {
                x0_m: 0.180,
                y0_m: -0.023,
                z0_m: 0.083,
                x1_m: 0.0,
                y1_m: -0.088,
                z1_m: 0.140,
                x2_m: 0.89,
            },
            (-15.0, 30.0),
            (-17.0, 17.0),
        )
    }

    /// The parameters of `arm`.
    pub fn for_arm(arm: ArmId) -> Self {
        match arm {
            ArmId::Arm1 => Self::arm1(),
            ArmId::Arm2 => Self::arm2(),
        }
    }

    fn from_table(
        arm: ArmId,
        links: LinkParams,
        theta_deg: (f64, f64),
        phi_deg: (f64, f64),
    ) -> Self {
        let v_max = MAX_END_EFFECTOR_SPEED_M_PER_S;
        Self {
            arm,
            links,
            position_limits: JointLimits {
                min: JointPosition {
                    d_m: -0.02,
                    theta_rad: theta_deg.0.to_radians(),
                    phi_rad: phi_deg.0.to_radians(),
                    twist_rad: -TWIST_LIMIT_RAD,
                },
                max: JointPosition {
                    d_m: 0.6,
                    theta_rad: theta_deg.1.to_radians(),
                    phi_rad: phi_deg.1.to_radians(),
                    twist_rad: TWIST_LIMIT_RAD,
                },
            },
            rate_limits: JointVelocity {
                d_m_per_s: v_max,
                theta_rad_per_s: v_max / (links.x2_m + links.z1_m),
                phi_rad_per_s: v_max / links.x2_m,
                twist_rad_per_s: TWIST_RATE_LIMIT_RAD_PER_S,
            },
            max_end_effector_speed_m_per_s: v_max,
            home: JointPosition::default(),
        }
    }

    /// Checks that every value is finite, lengths and rates positive, ranges non-empty and the
    /// home pose inside the limits.
    pub fn validate(&self) -> Result<(), ParamsError> {
        let arm = self.arm;
        let l = &self.links;
        let scalars = [
            ("links.x0_m", l.x0_m),
            ("links.y0_m", l.y0_m),
            ("links.z0_m", l.z0_m),
            ("links.x1_m", l.x1_m),
            ("links.y1_m", l.y1_m),
            ("links.z1_m", l.z1_m),
            ("links.x2_m", l.x2_m),
            (
                "max_end_effector_speed_m_per_s",
                self.max_end_effector_speed_m_per_s,
            ),
        ];
        for (field, value) in scalars {
            if !value.is_finite() {
                return Err(ParamsError::NonFinite { arm, field, value });
            }
        }
        if !self.position_limits.min.is_finite()
            || !self.position_limits.max.is_finite()
            || !self.home.is_finite()
        {
            return Err(ParamsError::NonFinite {
                arm,
                field: "position_limits/home",
                value: f64::NAN,
            });
        }
        let positives = [
            ("links.x2_m", l.x2_m),
            (
                "max_end_effector_speed_m_per_s",
                self.max_end_effector_speed_m_per_s,
            ),
            ("rate_limits.d_m_per_s", self.rate_limits.d_m_per_s),
            (
                "rate_limits.theta_rad_per_s",
                self.rate_limits.theta_rad_per_s,
            ),
            ("rate_limits.phi_rad_per_s", self.rate_limits.phi_rad_per_s),
            (
                "rate_limits.twist_rad_per_s",
                self.rate_limits.twist_rad_per_s,
            ),
        ];
        for (field, value) in positives {
            if !(value.is_finite() && value > 0.0) {
                return Err(ParamsError::NotPositive { arm, field, value });
            }
        }
        for joint in Joint::ALL {
            let (min, max) = (
                self.position_limits.min.get(joint),
                self.position_limits.max.get(joint),
            );
            if min > max {
                return Err(ParamsError::EmptyRange {
                    arm,
                    joint,
                    min,
                    max,
                });
            }
            let value = self.home.get(joint);
            if value < min || value > max {
                return Err(ParamsError::HomeOutsideLimits {
                    arm,
                    joint,
                    value,
                    min,
                    max,
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_1_values_are_transcribed() {
        let a1 = ArmParams::arm1();
        let a2 = ArmParams::arm2();
        assert_eq!(a1.links.x0_m, 0.147);
        assert_eq!(a2.links.x0_m, 0.180);
        assert_eq!(a1.links.y1_m, 0.093);
        assert_eq!(a2.links.y1_m, -0.088);
        assert_eq!(a1.links.z1_m, 0.138);
        assert_eq!(a2.links.z1_m, 0.140);
        assert_eq!(a1.links.x2_m, 0.90);
        assert_eq!(a2.links.x2_m, 0.89);
        assert_eq!(a1.position_limits.min.d_m, -0.02);
        assert_eq!(a2.position_limits.max.d_m, 0.6);
        assert!((a1.position_limits.min.theta_rad.to_degrees() + 17.0).abs() < 1e-12);
        assert!((a2.position_limits.min.theta_rad.to_degrees() + 15.0).abs() < 1e-12);
        assert!((a1.position_limits.max.phi_rad.to_degrees() - 19.0).abs() < 1e-12);
        assert!((a2.position_limits.max.phi_rad.to_degrees() - 17.0).abs() < 1e-12);
        assert_eq!(a1.max_end_effector_speed_m_per_s, 0.7748);
        assert_eq!(ArmParams::for_arm(ArmId::Arm2), a2);
    }

    #[test]
    fn arms_sit_side_by_side() {
        let a1 = ArmParams::arm1().links;
        let a2 = ArmParams::arm2().links;
        assert!(a1.y0_m + a1.y1_m > 0.1);
        assert!(a2.y0_m + a2.y1_m < -0.1);
    }

    #[test]
    fn built_in_parameters_validate() {
        assert_eq!(ArmParams::arm1().validate(), Ok(()));
        assert_eq!(ArmParams::arm2().validate(), Ok(()));
    }

    #[test]
    fn validation_names_the_bad_value() {
        let mut p = ArmParams::arm1();
        p.links.x2_m = -1.0;
        assert!(matches!(
            p.validate(),
            Err(ParamsError::NotPositive {
                field: "links.x2_m",
                ..
            })
        ));
        let mut p = ArmParams::arm2();
        p.position_limits.min.phi_rad = 1.0;
        assert!(matches!(
            p.validate(),
            Err(ParamsError::EmptyRange {
                joint: Joint::Yaw,
                ..
            })
        ));
        let mut p = ArmParams::arm1();
        p.home.d_m = 0.7;
        assert!(matches!(
            p.validate(),
            Err(ParamsError::HomeOutsideLimits {
                joint: Joint::Prismatic,
                ..
            })
        ));
        let mut p = ArmParams::arm1();
        p.links.z0_m = f64::NAN;
        assert!(matches!(
            p.validate(),
            Err(ParamsError::NonFinite {
                field: "links.z0_m",
                ..
            })
        ));
    }

    #[test]
    fn params_round_trip_through_toml_and_reject_unknown_keys() {
        let p = ArmParams::arm2();
        let text = toml::to_string(&p).unwrap();
        let back: ArmParams = toml::from_str(&text).unwrap();
        assert_eq!(back, p);
        let bad = text.replace("x2_m", "x3_m");
        assert!(toml::from_str::<ArmParams>(&bad).is_err());
    }

    #[test]
    fn limits_clamp_and_contain() {
        let lim = ArmParams::arm1().position_limits;
        let q = JointPosition::from_array([1.0, -1.0, 0.0, 10.0]);
        assert!(!lim.contains(&q));
        let c = lim.clamp(&q);
        assert!(lim.contains(&c));
        assert_eq!(c.d_m, 0.6);
        assert_eq!(c.theta_rad, lim.min.theta_rad);
        assert_eq!(c.twist_rad, TWIST_LIMIT_RAD);
    }
}
