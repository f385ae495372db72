//! Kinematics of one tube arm in the robot frame ([dual-arm sec. 3.2.1]): forward
//! kinematics (eq. 1), its closed-form inverse, the position Jacobian whose product with the
//! joint rates is eq. 2, and the structured inverse of that Jacobian used by the tracking
//! controller (eq. 5).
//!
//! Chain: the prismatic joint `D` slides the pitch axis to `(x0 + D, y0, z0)`; the pitch `theta`
//! rotates the offset `(x1, y1, z1)` to the yaw axis; the yaw `phi` swings the tube of length
//! `x2`. The tube direction is `(cos(theta) cos(phi), -sin(phi), sin(theta) cos(phi))`.
//! Within the Table 1 limits the Jacobian determinant `x2 cos(phi) (x1 cos(theta) -
//! z1 sin(theta) + x2 cos(phi) cos(theta))` stays above 0.5 m^2, so the arm has no singularity
//! in its workspace and the inverse is unique.

use thiserror::Error;

use crate::joint::{Joint, JointPosition, JointVelocity};
use crate::params::{ArmParams, LinkParams};

/// Why a target position has no valid joint solution.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum IkError {
    /// The target has a NaN or infinite coordinate.
    #[error("target position {target_m:?} m is not finite")]
    NonFinite {
        /// The rejected target, robot frame, m.
        target_m: [f64; 3],
    },
    /// The target is further sideways (y) from the arm than the tube can yaw.
    #[error(
        "target y = {y_m:.4} m is {offset_m:.4} m from the yaw axis, beyond the tube length {reach_m:.4} m"
    )]
    LateralOutOfReach {
        /// Target y, m.
        y_m: f64,
        /// Lateral offset from the yaw axis plane, m.
        offset_m: f64,
        /// Tube length `x2`, m.
        reach_m: f64,
    },
    /// The target is higher or lower than the tube can pitch to.
    #[error(
        "target z = {z_m:.4} m is {offset_m:.4} m from the pitch axis, beyond reach {reach_m:.4} m"
    )]
    VerticalOutOfReach {
        /// Target z, m.
        z_m: f64,
        /// Vertical offset from the pitch axis, m.
        offset_m: f64,
        /// Reach in the pitch plane at the required yaw, m.
        reach_m: f64,
    },
    /// A joint solution exists but violates the joint limits of Table 1.
    #[error("joint {joint} would be {value:.4}, outside its limits [{min:.4}, {max:.4}]")]
    JointLimit {
        /// The violated joint.
        joint: Joint,
        /// The required value (m or rad).
        value: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
}

/// Forward kinematics, eq. 1: end-effector position `p_e = [x_e, y_e, z_e]` in the robot frame,
/// metres. The twist joint does not change the position.
pub fn forward(links: &LinkParams, q: &JointPosition) -> [f64; 3] {
    let (st, ct) = q.theta_rad.sin_cos();
    let (sp, cp) = q.phi_rad.sin_cos();
    let l = links;
    [
        l.x0_m + l.x1_m * ct - l.z1_m * st + l.x2_m * ct * cp + q.d_m,
        l.y0_m + l.y1_m - l.x2_m * sp,
        l.z0_m + l.x1_m * st + l.z1_m * ct + l.x2_m * cp * st,
    ]
}

/// Position of the yaw axis (the root of the straight tube), robot frame, m: eq. 1 with
/// `x2 = 0`. With [`forward`] it bounds the tube body for clearance checks.
pub fn yaw_pivot(links: &LinkParams, q: &JointPosition) -> [f64; 3] {
    let no_tube = LinkParams {
        x2_m: 0.0,
        ..*links
    };
    forward(&no_tube, q)
}

/// Position Jacobian `J = d p_e / d [D, theta, phi]` (rows x, y, z), the matrix of eq. 2.
/// Units: column 0 dimensionless, columns 1-2 metres per radian.
pub fn jacobian(links: &LinkParams, q: &JointPosition) -> [[f64; 3]; 3] {
    let (st, ct) = q.theta_rad.sin_cos();
    let (sp, cp) = q.phi_rad.sin_cos();
    let l = links;
    [
        [
            1.0,
            -(l.x1_m * st + l.z1_m * ct + l.x2_m * st * cp),
            -l.x2_m * ct * sp,
        ],
        [0.0, 0.0, -l.x2_m * cp],
        [
            0.0,
            l.x1_m * ct - l.z1_m * st + l.x2_m * cp * ct,
            -l.x2_m * sp * st,
        ],
    ]
}

/// End-effector velocity, eq. 2: `p_e_dot = J(q) [D_dot, theta_dot, phi_dot]`, m/s.
pub fn end_effector_velocity(
    links: &LinkParams,
    q: &JointPosition,
    q_dot: &JointVelocity,
) -> [f64; 3] {
    let j = jacobian(links, q);
    let v = [q_dot.d_m_per_s, q_dot.theta_rad_per_s, q_dot.phi_rad_per_s];
    std::array::from_fn(|r| j[r][0] * v[0] + j[r][1] * v[1] + j[r][2] * v[2])
}

/// Smallest accepted magnitude of the two pivots of the structured inverse, m.
const MIN_PIVOT_M: f64 = 1e-6;

/// Solves `J(q) [D_dot, theta_dot, phi_dot] = task_velocity` by back-substitution, exploiting
/// the structure of eq. 2 (the y row involves only `phi_dot`, the z row only `theta_dot` and
/// `phi_dot`); this is the inversion written out in eq. 5. Returns joint rates
/// `[m/s, rad/s, rad/s]`, or `None` if a pivot vanishes (outside any reachable configuration).
pub fn solve_task_velocity(
    links: &LinkParams,
    q: &JointPosition,
    task_velocity_m_per_s: [f64; 3],
) -> Option<[f64; 3]> {
    let (st, ct) = q.theta_rad.sin_cos();
    let (sp, cp) = q.phi_rad.sin_cos();
    let l = links;
    let [u_x, u_y, u_z] = task_velocity_m_per_s;
    let yaw_pivot = l.x2_m * cp;
    let pitch_pivot = l.x1_m * ct - l.z1_m * st + l.x2_m * cp * ct;
    if yaw_pivot.abs() < MIN_PIVOT_M || pitch_pivot.abs() < MIN_PIVOT_M {
        return None;
    }
    let phi_dot = -u_y / yaw_pivot;
    let theta_dot = (u_z + phi_dot * l.x2_m * sp * st) / pitch_pivot;
    let d_dot = u_x
        + theta_dot * (l.x1_m * st + l.z1_m * ct + l.x2_m * st * cp)
        + phi_dot * l.x2_m * ct * sp;
    let out = [d_dot, theta_dot, phi_dot];
    out.iter().all(|v| v.is_finite()).then_some(out)
}

/// Closed-form inverse of eq. 1 without checking joint limits: `phi` from the y row, `theta`
/// from the z row, then `D` from the x row. Of the two pitch solutions it returns the one in
/// `(-pi/2, pi/2)` (the other points the tube backwards). The twist is returned as 0.
pub fn inverse_unchecked(links: &LinkParams, target_m: [f64; 3]) -> Result<JointPosition, IkError> {
    if target_m.iter().any(|v| !v.is_finite()) {
        return Err(IkError::NonFinite { target_m });
    }
    let l = links;
    let [x, y, z] = target_m;
    let lateral_m = l.y0_m + l.y1_m - y;
    let sin_phi = lateral_m / l.x2_m;
    if !(-1.0..=1.0).contains(&sin_phi) {
        return Err(IkError::LateralOutOfReach {
            y_m: y,
            offset_m: lateral_m,
            reach_m: l.x2_m,
        });
    }
    let phi = sin_phi.asin();
    // z - z0 = (x1 + x2 cos(phi)) sin(theta) + z1 cos(theta) = r sin(theta + alpha)
    let a = l.x1_m + l.x2_m * phi.cos();
    let b = l.z1_m;
    let r = a.hypot(b);
    let vertical_m = z - l.z0_m;
    if r <= 0.0 || vertical_m.abs() > r {
        return Err(IkError::VerticalOutOfReach {
            z_m: z,
            offset_m: vertical_m,
            reach_m: r,
        });
    }
    let theta = (vertical_m / r).asin() - b.atan2(a);
    let (st, ct) = theta.sin_cos();
    let d = x - l.x0_m - l.x1_m * ct + l.z1_m * st - l.x2_m * ct * phi.cos();
    Ok(JointPosition {
        d_m: d,
        theta_rad: theta,
        phi_rad: phi,
        twist_rad: 0.0,
    })
}

/// Inverse kinematics of eq. 1 with the Table 1 joint limits: the joint vector that puts the
/// end-effector at `target_m` (robot frame, m), twist 0, or the reason it cannot.
pub fn inverse(params: &ArmParams, target_m: [f64; 3]) -> Result<JointPosition, IkError> {
    let q = inverse_unchecked(&params.links, target_m)?;
    let lim = &params.position_limits;
    for joint in [Joint::Yaw, Joint::Pitch, Joint::Prismatic] {
        let (value, min, max) = (q.get(joint), lim.min.get(joint), lim.max.get(joint));
        if value < min || value > max {
            return Err(IkError::JointLimit {
                joint,
                value,
                min,
                max,
            });
        }
    }
    Ok(q)
}

/// True when `target_m` (robot frame, m) is inside the arm's workspace (section 3.2.1: the
/// inverse exists and respects the joint limits).
pub fn is_reachable(params: &ArmParams, target_m: [f64; 3]) -> bool {
    inverse(params, target_m).is_ok()
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // axis-indexed loops over small fixed arrays
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn random_q(params: &ArmParams, rng: &mut SmallRng) -> JointPosition {
        let (lo, hi) = (
            params.position_limits.min.to_array(),
            params.position_limits.max.to_array(),
        );
        JointPosition::from_array(std::array::from_fn(|i| rng.random_range(lo[i]..=hi[i])))
    }

    #[test]
    fn forward_at_zero_is_the_sum_of_offsets() {
        let p = ArmParams::arm1();
        let e = forward(&p.links, &JointPosition::default());
        assert!((e[0] - (0.147 + 0.90)).abs() < 1e-12);
        assert!((e[1] - (0.017 + 0.093)).abs() < 1e-12);
        assert!((e[2] - (0.083 + 0.138)).abs() < 1e-12);
    }

    #[test]
    fn forward_known_answer_arm2() {
        // Hand evaluation of eq. 1 for arm 2 at D = 0.3, theta = 20 deg, phi = -10 deg.
        let p = ArmParams::arm2();
        let q = JointPosition {
            d_m: 0.3,
            theta_rad: 20f64.to_radians(),
            phi_rad: (-10f64).to_radians(),
            twist_rad: 1.0,
        };
        let (st, ct) = (0.342_020_143_325_668_7, 0.939_692_620_785_908_4);
        let (sp, cp) = (-0.173_648_177_666_930_3, 0.984_807_753_012_208);
        let expected = [
            0.180 - 0.140 * st + 0.89 * ct * cp + 0.3,
            -0.023 - 0.088 - 0.89 * sp,
            0.083 + 0.140 * ct + 0.89 * cp * st,
        ];
        let e = forward(&p.links, &q);
        for i in 0..3 {
            assert!((e[i] - expected[i]).abs() < 1e-12, "axis {i}");
        }
    }

    #[test]
    fn inverse_of_forward_round_trips_on_random_reachable_points() {
        let mut rng = SmallRng::seed_from_u64(7);
        for params in [ArmParams::arm1(), ArmParams::arm2()] {
            for _ in 0..2000 {
                let q = random_q(&params, &mut rng).with_twist(0.0);
                let p = forward(&params.links, &q);
                // Points on the limit boundary may round just outside; use the unchecked solver
                // for the round trip and the checked one for strictly interior points.
                let back = inverse_unchecked(&params.links, p).unwrap();
                let p2 = forward(&params.links, &back);
                for i in 0..3 {
                    assert!((p[i] - p2[i]).abs() < 1e-10, "FK(IK(p)) != p: {p:?} {p2:?}");
                }
                let dq = back.to_array();
                let q_arr = q.to_array();
                for i in 0..3 {
                    assert!(
                        (dq[i] - q_arr[i]).abs() < 1e-9,
                        "IK not unique: {q:?} {back:?}"
                    );
                }
                assert!(is_reachable(&params, p) || !params.position_limits.contains(&back));
            }
        }
    }

    #[test]
    fn inverse_rejects_with_reasons() {
        let p = ArmParams::arm1();
        assert!(matches!(
            inverse(&p, [f64::NAN, 0.0, 0.3]),
            Err(IkError::NonFinite { .. })
        ));
        assert!(matches!(
            inverse(&p, [1.2, 1.5, 0.3]),
            Err(IkError::LateralOutOfReach { .. })
        ));
        assert!(matches!(
            inverse(&p, [1.2, 0.1, 2.0]),
            Err(IkError::VerticalOutOfReach { .. })
        ));
        // Straight ahead but too far for the prismatic joint.
        assert!(matches!(
            inverse(&p, [2.5, 0.11, 0.221]),
            Err(IkError::JointLimit {
                joint: Joint::Prismatic,
                ..
            })
        ));
        // Lateral offset 0.5 m needs |phi| = 33.7 deg > 19 deg.
        assert!(matches!(
            inverse(&p, [1.2, 0.11 - 0.5, 0.221]),
            Err(IkError::JointLimit {
                joint: Joint::Yaw,
                ..
            })
        ));
        // Height needing theta > 30 deg.
        assert!(matches!(
            inverse(&p, [1.0, 0.11, 0.8]),
            Err(IkError::JointLimit {
                joint: Joint::Pitch,
                ..
            })
        ));
        assert!(!is_reachable(&p, [2.5, 0.11, 0.221]));
        assert!(is_reachable(&p, [1.3, 0.0, 0.35]));
    }

    #[test]
    fn jacobian_matches_central_finite_differences() {
        let mut rng = SmallRng::seed_from_u64(11);
        let h = 1e-6;
        for params in [ArmParams::arm1(), ArmParams::arm2()] {
            for _ in 0..500 {
                let q = random_q(&params, &mut rng);
                let j = jacobian(&params.links, &q);
                for col in 0..3 {
                    let mut plus = q.to_array();
                    let mut minus = q.to_array();
                    plus[col] += h;
                    minus[col] -= h;
                    let fp = forward(&params.links, &JointPosition::from_array(plus));
                    let fm = forward(&params.links, &JointPosition::from_array(minus));
                    for row in 0..3 {
                        let fd = (fp[row] - fm[row]) / (2.0 * h);
                        assert!(
                            (fd - j[row][col]).abs() < 1e-7,
                            "J[{row}][{col}] = {} vs fd {fd}",
                            j[row][col]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn velocity_matches_eq_2_as_printed() {
        let params = ArmParams::arm1();
        let l = params.links;
        let mut rng = SmallRng::seed_from_u64(3);
        for _ in 0..200 {
            let q = random_q(&params, &mut rng);
            let qd =
                JointVelocity::from_array(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let (th, ph) = (q.theta_rad, q.phi_rad);
            let (d, t, f) = (qd.d_m_per_s, qd.theta_rad_per_s, qd.phi_rad_per_s);
            let eq2 = [
                -t * (l.x1_m * th.sin() + l.z1_m * th.cos() + l.x2_m * th.sin() * ph.cos())
                    - f * l.x2_m * th.cos() * ph.sin()
                    + d,
                -f * l.x2_m * ph.cos(),
                t * (l.x1_m * th.cos() - l.z1_m * th.sin() + l.x2_m * ph.cos() * th.cos())
                    - f * l.x2_m * ph.sin() * th.sin(),
            ];
            let v = end_effector_velocity(&l, &q, &qd);
            for i in 0..3 {
                assert!((v[i] - eq2[i]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn structured_inverse_solves_the_jacobian_system() {
        let mut rng = SmallRng::seed_from_u64(5);
        for params in [ArmParams::arm1(), ArmParams::arm2()] {
            for _ in 0..500 {
                let q = random_q(&params, &mut rng);
                let u: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                let qd = solve_task_velocity(&params.links, &q, u).unwrap();
                let v = end_effector_velocity(
                    &params.links,
                    &q,
                    &JointVelocity::from_array([qd[0], qd[1], qd[2], 0.0]),
                );
                for i in 0..3 {
                    assert!((v[i] - u[i]).abs() < 1e-12);
                }
                // Determinant bound quoted in the module docs.
                let j = jacobian(&params.links, &q);
                let det = j[1][2] * -j[2][1];
                assert!(det.abs() > 0.5, "det {det}");
            }
        }
    }

    #[test]
    fn yaw_pivot_is_one_tube_length_behind_the_tip() {
        let params = ArmParams::arm2();
        let q = JointPosition::from_array([0.2, 0.3, -0.2, 0.0]);
        let tip = forward(&params.links, &q);
        let pivot = yaw_pivot(&params.links, &q);
        let len = (0..3)
            .map(|i| (tip[i] - pivot[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!((len - params.links.x2_m).abs() < 1e-12);
    }
}
