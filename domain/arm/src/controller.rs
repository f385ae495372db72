//! Robust trajectory-tracking controller of one arm ([dual-arm sec. 3.2.3, eq. 4-6]),
//! derived in `processes/arm/CONTROLLER.md`.
//!
//! With the task error `e = p_e(q) - p_r` (eq. 4) the controller asks for the end-effector
//! velocity
//!
//! `u = v_r - K e - eta`, `eta_dot = G e + B sgn(e)` (per axis; sgn(0) = +1 as in the paper)
//!
//! and converts it to joint rates through the structured inverse of the eq. 2 Jacobian, which
//! is exactly the back-substitution printed as eq. 5. `eta` is the RISE-like integral of eq. 6
//! (Xian et al. 2004): the paper uses one gain `t` for both the `e` and `sgn(e)` terms; we keep
//! them separate (`G`, `B`). The twist joint, absent from eq. 5, gets rate feedforward plus a
//! proportional term. Every command is clamped to the joint rate limits and so that one period
//! cannot carry a joint past its position limit; while any joint is clamped the integral is
//! frozen (anti-windup) and `|eta|` is bounded.

use serde::{Deserialize, Serialize};
use thiserror::Error;
use tracing::{trace, warn};

use crate::trajectory::JointSample;
use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::kinematics::{end_effector_velocity, forward, solve_task_velocity};
use harvest_robot_model::params::{ArmParams, LinkParams};

/// Longest period integrated into `eta` in one step, s (a stalled loop must not wind it up).
pub const MAX_INTEGRATION_STEP_S: f64 = 0.05;

/// Controller gains, one value per robot-frame axis `[x, y, z]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingGains {
    /// `K`: proportional gain, 1/s (paper `k_x, k_y, k_z`).
    pub proportional_per_s: [f64; 3],
    /// `G`: gain of the integrated error in `eta`, 1/s^2 (paper `t_x, t_y, t_z` on `e`).
    pub integral_per_s2: [f64; 3],
    /// `B`: gain of the integrated sign of the error in `eta`, m/s^2 (paper `t_x, t_y, t_z` on
    /// `sgn(e)`).
    pub robust_m_per_s2: [f64; 3],
    /// Bound on `|eta|` per axis, m/s (anti-windup; not in the paper).
    pub robust_term_limit_m_per_s: [f64; 3],
    /// Proportional gain of the twist joint, 1/s (the twist is not part of eq. 5).
    pub twist_proportional_per_s: f64,
}

impl Default for TrackingGains {
    /// `K = 12/s`, `G = 36/s^2` (critically damped error dynamics, double pole at -6/s),
    /// `B = 0.02 m/s^2`, `|eta| <= 0.1 m/s`, twist 10/s.
    fn default() -> Self {
        Self {
            proportional_per_s: [12.0; 3],
            integral_per_s2: [36.0; 3],
            robust_m_per_s2: [0.02; 3],
            robust_term_limit_m_per_s: [0.1; 3],
            twist_proportional_per_s: 10.0,
        }
    }
}

/// Why a gain set is unusable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GainsError {
    /// A gain is NaN, infinite or negative.
    #[error("gain `{field}` axis {axis} must be finite and >= 0, got {value}")]
    Invalid {
        /// Gain name.
        field: &'static str,
        /// Axis index (0 x, 1 y, 2 z; 0 for scalars).
        axis: usize,
        /// The rejected value.
        value: f64,
    },
    /// A proportional gain is zero (the error dynamics would not be damped).
    #[error("proportional gain axis {axis} must be > 0, got {value}")]
    ZeroProportional {
        /// Axis index.
        axis: usize,
        /// The rejected value.
        value: f64,
    },
}

impl TrackingGains {
    /// Gains in the paper's form: `k` for eq. 5 and one `t` per axis multiplying both the
    /// error and its sign inside eq. 6 (numerically, `G = t` in 1/s^2 and `B = t` in m/s^2).
    pub fn paper_form(k: [f64; 3], t: [f64; 3], twist_proportional_per_s: f64) -> Self {
        Self {
            proportional_per_s: k,
            integral_per_s2: t,
            robust_m_per_s2: t,
            twist_proportional_per_s,
            ..Self::default()
        }
    }

    /// Checks that every gain is finite and non-negative and `K > 0`.
    pub fn validate(&self) -> Result<(), GainsError> {
        let arrays = [
            ("proportional_per_s", self.proportional_per_s),
            ("integral_per_s2", self.integral_per_s2),
            ("robust_m_per_s2", self.robust_m_per_s2),
            ("robust_term_limit_m_per_s", self.robust_term_limit_m_per_s),
            (
                "twist_proportional_per_s",
                [self.twist_proportional_per_s; 3],
            ),
        ];
        for (field, values) in arrays {
            for (axis, &value) in values.iter().enumerate() {
                if !(value.is_finite() && value >= 0.0) {
                    return Err(GainsError::Invalid { field, axis, value });
                }
            }
        }
        for (axis, &value) in self.proportional_per_s.iter().enumerate() {
            if value <= 0.0 {
                return Err(GainsError::ZeroProportional { axis, value });
            }
        }
        Ok(())
    }
}

/// The reference the controller tracks at one instant: `p_r(t)`, `v_r(t)` in the robot frame
/// (eq. 4-5; the acceleration is not used, the servos take rate inputs) and the twist reference.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackingReference {
    /// Reference end-effector position `p_r`, m.
    pub position_m: [f64; 3],
    /// Reference end-effector velocity `v_r`, m/s.
    pub velocity_m_per_s: [f64; 3],
    /// Reference twist angle, rad.
    pub twist_rad: f64,
    /// Reference twist rate, rad/s.
    pub twist_rad_per_s: f64,
}

impl TrackingReference {
    /// Maps a joint-space trajectory sample to the task-space reference:
    /// `p_r = FK(q_r)` (eq. 1), `v_r = J(q_r) q_dot_r` (eq. 2).
    pub fn from_joint_sample(links: &LinkParams, sample: &JointSample) -> Self {
        Self {
            position_m: forward(links, &sample.position),
            velocity_m_per_s: end_effector_velocity(links, &sample.position, &sample.velocity),
            twist_rad: sample.position.twist_rad,
            twist_rad_per_s: sample.velocity.twist_rad_per_s,
        }
    }

    /// A reference at rest at joint position `q`.
    pub fn hold(links: &LinkParams, q: &JointPosition) -> Self {
        Self {
            position_m: forward(links, q),
            velocity_m_per_s: [0.0; 3],
            twist_rad: q.twist_rad,
            twist_rad_per_s: 0.0,
        }
    }

    fn is_finite(&self) -> bool {
        self.position_m
            .iter()
            .chain(&self.velocity_m_per_s)
            .chain([&self.twist_rad, &self.twist_rad_per_s])
            .all(|v| v.is_finite())
    }
}

/// Rate command for the four servos.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointCommand {
    /// Commanded joint rates, within the rate limits and not driving any joint past its
    /// position limit within one period.
    pub velocity: JointVelocity,
    /// True when at least one joint rate was reduced by the clamps.
    pub clamped: bool,
    /// True when the controller refused to compute (non-finite input, bad period or a
    /// degenerate Jacobian) and commands zero rates.
    pub stopped: bool,
}

impl JointCommand {
    /// Zero rates, marked as a stop.
    pub const STOP: Self = Self {
        velocity: JointVelocity::ZERO,
        clamped: false,
        stopped: true,
    };
}

/// Clamps joint rates `raw` so that `|rate| <= params.rate_limits` and, if `measured` is inside
/// the position limits, `measured + rate dt_s` stays inside them; a joint already outside its
/// limits may only move back. Returns the clamped rates and whether anything changed.
pub fn clamp_rates(
    params: &ArmParams,
    measured: &JointPosition,
    raw: &JointVelocity,
    dt_s: f64,
) -> (JointVelocity, bool) {
    let q = measured.to_array();
    let lo = params.position_limits.min.to_array();
    let hi = params.position_limits.max.to_array();
    let v_max = params.rate_limits.to_array();
    let raw = raw.to_array();
    let mut out = [0.0; 4];
    let mut clamped = false;
    for i in 0..4 {
        let floor = ((lo[i] - q[i]) / dt_s).min(0.0);
        let ceil = ((hi[i] - q[i]) / dt_s).max(0.0);
        let v = raw[i].clamp(floor, ceil).clamp(-v_max[i], v_max[i]);
        clamped |= v != raw[i];
        out[i] = v;
    }
    (JointVelocity::from_array(out), clamped)
}

/// The paper's sign function: +1 for `x >= 0`, -1 otherwise.
fn sgn(x: f64) -> f64 {
    if x >= 0.0 { 1.0 } else { -1.0 }
}

/// Trajectory-tracking controller of one arm; call [`TrackingController::step`] every period
/// (>= 200 Hz, section 2.2).
#[derive(Debug, Clone, PartialEq)]
pub struct TrackingController {
    params: ArmParams,
    gains: TrackingGains,
    eta_m_per_s: [f64; 3],
    last_error_m: [f64; 3],
}

impl TrackingController {
    /// A controller with `eta = 0`.
    pub fn new(params: ArmParams, gains: TrackingGains) -> Result<Self, GainsError> {
        gains.validate()?;
        Ok(Self {
            params,
            gains,
            eta_m_per_s: [0.0; 3],
            last_error_m: [0.0; 3],
        })
    }

    /// Clears the integral state (call when a new motion starts from rest).
    pub fn reset(&mut self) {
        self.eta_m_per_s = [0.0; 3];
        self.last_error_m = [0.0; 3];
    }

    /// The robust integral term `eta` (eq. 6), m/s.
    pub fn robust_term_m_per_s(&self) -> [f64; 3] {
        self.eta_m_per_s
    }

    /// Tracking error `e = p_e - p_r` (eq. 4) of the last step, m.
    pub fn last_error_m(&self) -> [f64; 3] {
        self.last_error_m
    }

    /// The gains in use.
    pub fn gains(&self) -> &TrackingGains {
        &self.gains
    }

    /// One control period: `measured` joint positions, the `reference` at the same instant and
    /// the period `dt_s` (s) until the next step. Returns clamped joint rates; zero rates with
    /// `stopped` if any input is non-finite, `dt_s <= 0` or the Jacobian is degenerate.
    pub fn step(
        &mut self,
        reference: &TrackingReference,
        measured: &JointPosition,
        dt_s: f64,
    ) -> JointCommand {
        let valid = dt_s.is_finite() && dt_s > 0.0 && measured.is_finite() && reference.is_finite();
        if !valid {
            warn!(
                dt_s,
                ?measured,
                ?reference,
                "tracking controller stopped: invalid input"
            );
            return JointCommand::STOP;
        }
        let links = &self.params.links;
        let p = forward(links, measured);
        let g = &self.gains;
        let error: [f64; 3] = std::array::from_fn(|i| p[i] - reference.position_m[i]);
        let u: [f64; 3] = std::array::from_fn(|i| {
            reference.velocity_m_per_s[i] - g.proportional_per_s[i] * error[i] - self.eta_m_per_s[i]
        });
        let Some([d_dot, theta_dot, phi_dot]) = solve_task_velocity(links, measured, u) else {
            warn!(
                ?measured,
                "tracking controller stopped: degenerate Jacobian"
            );
            return JointCommand::STOP;
        };
        let twist_dot = reference.twist_rad_per_s
            - g.twist_proportional_per_s * (measured.twist_rad - reference.twist_rad);
        let raw = JointVelocity {
            d_m_per_s: d_dot,
            theta_rad_per_s: theta_dot,
            phi_rad_per_s: phi_dot,
            twist_rad_per_s: twist_dot,
        };
        let (velocity, clamped) = clamp_rates(&self.params, measured, &raw, dt_s);
        if !clamped {
            let h = dt_s.min(MAX_INTEGRATION_STEP_S);
            for (i, (eta, e)) in self.eta_m_per_s.iter_mut().zip(error).enumerate() {
                let rate = g.integral_per_s2[i] * e + g.robust_m_per_s2[i] * sgn(e);
                let limit = g.robust_term_limit_m_per_s[i];
                *eta = (*eta + h * rate).clamp(-limit, limit);
            }
        }
        self.last_error_m = error;
        trace!(?error, eta = ?self.eta_m_per_s, ?velocity, clamped, "tracking step");
        JointCommand {
            velocity,
            clamped,
            stopped: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::servo_model::FirstOrderServo;
    use crate::trajectory::JointTrajectory;
    use harvest_robot_model::kinematics::inverse;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    const CONTROL_DT_S: f64 = 0.005; // 200 Hz
    const PLANT_DT_S: f64 = 0.001;

    fn norm(v: [f64; 3]) -> f64 {
        v.iter().map(|c| c * c).sum::<f64>().sqrt()
    }

    #[test]
    fn first_step_equals_eq_5_as_printed_with_the_x_row_corrected() {
        let params = ArmParams::arm1();
        let l = params.links;
        let gains = TrackingGains::paper_form([5.0, 6.0, 7.0], [1.0; 3], 0.0);
        let mut rng = SmallRng::seed_from_u64(21);
        for _ in 0..200 {
            let mut c = TrackingController::new(params, gains).unwrap();
            let q = JointPosition::from_array([
                rng.random_range(0.1..0.5),
                rng.random_range(-0.2..0.4),
                rng.random_range(-0.25..0.25),
                0.0,
            ]);
            let p = forward(&l, &q);
            let r = TrackingReference {
                position_m: std::array::from_fn(|i| p[i] + rng.random_range(-0.005..0.005)),
                velocity_m_per_s: std::array::from_fn(|_| rng.random_range(-0.05..0.05)),
                twist_rad: 0.0,
                twist_rad_per_s: 0.0,
            };
            let cmd = c.step(&r, &q, CONTROL_DT_S);
            assert!(!cmd.clamped && !cmd.stopped);
            // Eq. 5 with eta = 0; k1 = k_y, k2 = k_z, and x2 moved inside the bracket of D_dot.
            let e: [f64; 3] = std::array::from_fn(|i| p[i] - r.position_m[i]);
            let v = r.velocity_m_per_s;
            let (th, ph) = (q.theta_rad, q.phi_rad);
            let phi_dot = (6.0 * e[1] - v[1]) / (l.x2_m * ph.cos());
            let theta_dot = (-7.0 * e[2] + l.x2_m * phi_dot * th.sin() * ph.sin() + v[2])
                / (l.x2_m * th.cos() * ph.cos() + l.x1_m * th.cos() - l.z1_m * th.sin());
            let d_dot = -5.0 * e[0]
                + theta_dot
                    * (l.x2_m * th.sin() * ph.cos() + l.x1_m * th.sin() + l.z1_m * th.cos())
                + l.x2_m * phi_dot * th.cos() * ph.sin()
                + v[0];
            assert!((cmd.velocity.phi_rad_per_s - phi_dot).abs() < 1e-12);
            assert!((cmd.velocity.theta_rad_per_s - theta_dot).abs() < 1e-12);
            assert!((cmd.velocity.d_m_per_s - d_dot).abs() < 1e-12);
        }
    }

    #[test]
    fn output_is_always_within_rate_and_position_limits() {
        let mut rng = SmallRng::seed_from_u64(22);
        for params in [ArmParams::arm1(), ArmParams::arm2()] {
            let gains = TrackingGains {
                proportional_per_s: [500.0; 3],
                integral_per_s2: [1e4; 3],
                robust_m_per_s2: [10.0; 3],
                robust_term_limit_m_per_s: [5.0; 3],
                twist_proportional_per_s: 500.0,
            };
            let mut c = TrackingController::new(params, gains).unwrap();
            let lo = params.position_limits.min.to_array();
            let hi = params.position_limits.max.to_array();
            let v_max = params.rate_limits.to_array();
            for _ in 0..20_000 {
                let q = JointPosition::from_array(std::array::from_fn(|i| {
                    let span = hi[i] - lo[i];
                    rng.random_range(lo[i] - 0.05 * span..=hi[i] + 0.05 * span)
                }));
                let r = TrackingReference {
                    position_m: [
                        rng.random_range(0.5..2.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-0.5..1.0),
                    ],
                    velocity_m_per_s: std::array::from_fn(|_| rng.random_range(-2.0..2.0)),
                    twist_rad: rng.random_range(-4.0..4.0),
                    twist_rad_per_s: rng.random_range(-10.0..10.0),
                };
                let dt = rng.random_range(0.001..0.02);
                let cmd = c.step(&r, &q, dt);
                let v = cmd.velocity.to_array();
                let qa = q.to_array();
                for i in 0..4 {
                    assert!(v[i].abs() <= v_max[i], "rate limit joint {i}: {}", v[i]);
                    let next = qa[i] + v[i] * dt;
                    if qa[i] >= lo[i] && qa[i] <= hi[i] {
                        assert!(next >= lo[i] - 1e-12 && next <= hi[i] + 1e-12);
                    } else if qa[i] < lo[i] {
                        assert!(v[i] >= 0.0, "joint {i} driven further below its limit");
                    } else {
                        assert!(v[i] <= 0.0, "joint {i} driven further above its limit");
                    }
                }
            }
        }
    }

    #[test]
    fn invalid_inputs_stop_the_arm() {
        let params = ArmParams::arm1();
        let mut c = TrackingController::new(params, TrackingGains::default()).unwrap();
        let r = TrackingReference::hold(&params.links, &params.home);
        assert_eq!(c.step(&r, &params.home, 0.0), JointCommand::STOP);
        assert_eq!(c.step(&r, &params.home, f64::NAN), JointCommand::STOP);
        let mut bad = params.home;
        bad.theta_rad = f64::NAN;
        assert_eq!(c.step(&r, &bad, CONTROL_DT_S), JointCommand::STOP);
        let mut bad_ref = r;
        bad_ref.velocity_m_per_s[1] = f64::INFINITY;
        assert_eq!(
            c.step(&bad_ref, &params.home, CONTROL_DT_S),
            JointCommand::STOP
        );
        // At the reference at rest the command is (almost) zero.
        let cmd = c.step(&r, &params.home, CONTROL_DT_S);
        assert!(
            norm([
                cmd.velocity.d_m_per_s,
                cmd.velocity.theta_rad_per_s,
                cmd.velocity.phi_rad_per_s
            ]) < 1e-9
        );
    }

    #[test]
    fn gains_validation() {
        assert_eq!(TrackingGains::default().validate(), Ok(()));
        let mut g = TrackingGains::default();
        g.integral_per_s2[2] = -1.0;
        assert!(matches!(
            g.validate(),
            Err(GainsError::Invalid {
                field: "integral_per_s2",
                axis: 2,
                ..
            })
        ));
        let mut g = TrackingGains::default();
        g.proportional_per_s[0] = 0.0;
        assert!(matches!(
            g.validate(),
            Err(GainsError::ZeroProportional { axis: 0, .. })
        ));
        assert!(TrackingController::new(ArmParams::arm1(), g).is_err());
    }

    /// Bound on the tracking error at full speed: below the +-1.5 cm localisation tolerance of
    /// the end-effector (section 2.2) and below the open-loop servo lag `tau * v_max` = 23 mm.
    const MAX_ERROR_BOUND_M: f64 = 0.015;

    struct Run {
        max_error_m: f64,
        /// RMS error while holding the goal (from 0.5 s after the trajectory ends).
        hold_rms_error_m: f64,
        final_error_m: f64,
        any_clamped: bool,
    }

    /// Closed loop: 200 Hz controller, first-order servos (30 ms lag) simulated at 1 kHz with a
    /// joint-rate disturbance, tracking a 3-waypoint quintic trajectory then holding 3 s.
    fn closed_loop(gains: TrackingGains, disturbance: impl Fn(f64) -> JointVelocity) -> Run {
        let params = ArmParams::arm1();
        let waypoints = vec![
            params.home,
            inverse(&params, [1.30, 0.0, 0.35]).unwrap(),
            inverse(&params, [1.45, 0.15, 0.45])
                .unwrap()
                .with_twist(0.5),
        ];
        let traj = JointTrajectory::plan(&params, &waypoints, &JointVelocity::ZERO, 1.0).unwrap();
        let mut servo = FirstOrderServo::new(params.position_limits, 0.03, params.home);
        let mut c = TrackingController::new(params, gains).unwrap();
        let end_s = traj.duration_s() + 3.0;
        let steps = (end_s / PLANT_DT_S).round() as usize;
        let per_control = (CONTROL_DT_S / PLANT_DT_S).round() as usize;
        let mut cmd = JointCommand::default();
        let (mut max_e, mut sum_sq, mut n, mut final_e, mut any_clamped) =
            (0.0f64, 0.0, 0usize, 0.0, false);
        let hold_from_s = traj.duration_s() + 0.5;
        for k in 0..steps {
            let t = k as f64 * PLANT_DT_S;
            if k % per_control == 0 {
                let reference =
                    TrackingReference::from_joint_sample(&params.links, &traj.sample(t));
                cmd = c.step(&reference, &servo.position, CONTROL_DT_S);
                any_clamped |= cmd.clamped;
                let e = norm(c.last_error_m());
                max_e = max_e.max(e);
                if t >= hold_from_s {
                    sum_sq += e * e;
                    n += 1;
                }
                final_e = e;
            }
            servo.step(&cmd.velocity, &disturbance(t), PLANT_DT_S);
        }
        Run {
            max_error_m: max_e,
            hold_rms_error_m: (sum_sq / n.max(1) as f64).sqrt(),
            final_error_m: final_e,
            any_clamped,
        }
    }

    fn constant_disturbance(_t: f64) -> JointVelocity {
        JointVelocity::from_array([0.03, 0.02, -0.02, 0.0])
    }

    fn varying_disturbance(t: f64) -> JointVelocity {
        let w = 2.0 * std::f64::consts::PI * 0.7;
        JointVelocity::from_array([
            0.03 + 0.02 * (w * t).sin(),
            0.02 + 0.01 * (1.3 * w * t).cos(),
            -0.02 + 0.01 * (0.7 * w * t).sin(),
            0.0,
        ])
    }

    #[test]
    fn integral_sign_term_removes_a_constant_disturbance() {
        let rise = closed_loop(TrackingGains::default(), constant_disturbance);
        let p_only = closed_loop(
            TrackingGains {
                integral_per_s2: [0.0; 3],
                robust_m_per_s2: [0.0; 3],
                ..TrackingGains::default()
            },
            constant_disturbance,
        );
        println!(
            "constant disturbance: RISE max {:.2} mm final {:.3} mm; P-only final {:.3} mm",
            rise.max_error_m * 1e3,
            rise.final_error_m * 1e3,
            p_only.final_error_m * 1e3
        );
        assert!(
            rise.final_error_m < 3e-4,
            "RISE final error {}",
            rise.final_error_m
        );
        // P-only settles at |J d| / K, several millimetres.
        assert!(
            p_only.final_error_m > 2e-3,
            "P final error {}",
            p_only.final_error_m
        );
        assert!(
            rise.max_error_m < MAX_ERROR_BOUND_M,
            "RISE max error {}",
            rise.max_error_m
        );
        assert!(!rise.any_clamped);
    }

    #[test]
    fn tracking_error_stays_bounded_under_a_time_varying_disturbance() {
        let rise = closed_loop(TrackingGains::default(), varying_disturbance);
        let p_only = closed_loop(
            TrackingGains {
                integral_per_s2: [0.0; 3],
                robust_m_per_s2: [0.0; 3],
                ..TrackingGains::default()
            },
            varying_disturbance,
        );
        println!(
            "varying disturbance: RISE max {:.2} mm, hold rms {:.3} mm; P-only hold rms {:.3} mm",
            rise.max_error_m * 1e3,
            rise.hold_rms_error_m * 1e3,
            p_only.hold_rms_error_m * 1e3
        );
        assert!(
            rise.max_error_m < MAX_ERROR_BOUND_M,
            "max error {}",
            rise.max_error_m
        );
        assert!(
            rise.final_error_m < 2e-3,
            "final error {}",
            rise.final_error_m
        );
        assert!(
            rise.hold_rms_error_m < 0.5 * p_only.hold_rms_error_m,
            "RISE hold rms {} vs P hold rms {}",
            rise.hold_rms_error_m,
            p_only.hold_rms_error_m
        );
    }

    /// Reports (does not assert) the cost of one controller step. Run:
    /// `cargo test -p harvest-arm --release -- --ignored --nocapture report_step_time`.
    #[test]
    #[ignore = "performance report, run explicitly"]
    fn report_step_time() {
        let params = ArmParams::arm1();
        let mut c = TrackingController::new(params, TrackingGains::default()).unwrap();
        let q = inverse(&params, [1.3, 0.0, 0.35]).unwrap();
        let mut r = TrackingReference::hold(&params.links, &q);
        r.velocity_m_per_s = [0.1, -0.05, 0.02];
        let n = 1_000_000;
        let t0 = std::time::Instant::now();
        for k in 0..n {
            r.position_m[0] += 1e-9 * k as f64;
            std::hint::black_box(c.step(&r, &q, CONTROL_DT_S));
        }
        let ns = t0.elapsed().as_secs_f64() * 1e9 / n as f64;
        println!("controller step: {ns:.0} ns (budget at 200 Hz: 5 ms)");
    }

    #[test]
    fn undisturbed_tracking_is_tight() {
        let run = closed_loop(TrackingGains::default(), |_| JointVelocity::ZERO);
        assert!(
            run.max_error_m < MAX_ERROR_BOUND_M,
            "max error {}",
            run.max_error_m
        );
        assert!(
            run.final_error_m < 3e-4,
            "final error {}",
            run.final_error_m
        );
    }
}
