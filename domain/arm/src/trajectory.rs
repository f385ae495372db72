//! Quintic spline trajectories ([dual-arm sec. 3.2.2, eq. 3]) and their time scaling.
//!
//! [`QuinticSpline`] interpolates `n` timed waypoints, independently per axis, with one quintic
//! polynomial per segment (eq. 3, written in local time `tau = t - t_i` for conditioning). The
//! raw waypoints are augmented as the paper describes: interior velocities are central
//! differences of positions, interior accelerations central differences of those velocities;
//! the first waypoint takes the measured initial velocity and zero acceleration, the last one
//! zero velocity and acceleration. Each segment matches position, velocity and acceleration at
//! both ends, so the curve passes through every waypoint and is C2-continuous.
//!
//! [`JointTrajectory`] applies this in joint space `[D, theta, phi, twist]` and chooses the
//! waypoint times itself: segment durations start from the rest-to-rest quintic estimate
//! (peak speed = 1.875 x mean speed) and are then scaled uniformly until the sampled peak of
//! every joint rate and of the end-effector speed `|J(q) q_dot|` (eq. 2) sits just below the
//! limits times a speed fraction (the field tests ran at 0.6 of the maximum, section 4.2).
//!
//! Planning runs inside the 200 Hz control tick (a motion starts on the tick its phase
//! begins), so it allocates nothing: a spline holds at most [`MAX_WAYPOINTS`] waypoints in a
//! fixed array, and the time scaling works on arrays of that size.

use thiserror::Error;

use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::kinematics::{end_effector_velocity, forward};
use harvest_robot_model::params::ArmParams;

/// Most waypoints a spline takes (the picking cycle plans through at most three: where the arm
/// is, a via point, the goal).
pub const MAX_WAYPOINTS: usize = 16;

/// Why a trajectory could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TrajectoryError {
    /// Fewer than two waypoints were given.
    #[error("a trajectory needs at least 2 waypoints, got {count}")]
    TooFewWaypoints {
        /// Number of waypoints given.
        count: usize,
    },
    /// More than [`MAX_WAYPOINTS`] waypoints were given.
    #[error("a trajectory takes at most {MAX_WAYPOINTS} waypoints, got {count}")]
    TooManyWaypoints {
        /// Number of waypoints given.
        count: usize,
    },
    /// The time and position lists have different lengths.
    #[error("{times} waypoint times but {positions} waypoint positions")]
    LengthMismatch {
        /// Number of times.
        times: usize,
        /// Number of positions.
        positions: usize,
    },
    /// Waypoint times are not strictly increasing.
    #[error("waypoint time {index} ({time_s} s) does not follow the previous one ({previous_s} s)")]
    NonIncreasingTime {
        /// Index of the offending waypoint.
        index: usize,
        /// Its time, s.
        time_s: f64,
        /// The previous waypoint's time, s.
        previous_s: f64,
    },
    /// A waypoint time, position or the initial velocity is NaN or infinite.
    #[error("waypoint {index} has a non-finite time, position or velocity")]
    NonFinite {
        /// Index of the offending waypoint (0 also covers the initial velocity).
        index: usize,
    },
    /// A waypoint after the first lies outside the joint limits.
    #[error("waypoint {index} is outside the joint limits: {position:?}")]
    OutsideLimits {
        /// Index of the offending waypoint.
        index: usize,
        /// The waypoint.
        position: JointPosition,
    },
    /// The speed fraction is not in `(0, 1]`.
    #[error("speed fraction {value} is not in (0, 1]")]
    BadSpeedFraction {
        /// The rejected value.
        value: f64,
    },
    /// Time scaling did not converge below the limits.
    #[error("time scaling left the peak at {ratio:.3} x the limit after {iterations} iterations")]
    LimitsNotMet {
        /// Peak rate over limit.
        ratio: f64,
        /// Iterations spent.
        iterations: usize,
    },
}

/// Position, velocity and acceleration of an `N`-axis trajectory at one instant (eq. 3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectorySample<const N: usize> {
    /// `p_r(t)` per axis.
    pub position: [f64; N],
    /// `v_r(t)` per axis, per second.
    pub velocity: [f64; N],
    /// `a_r(t)` per axis, per second squared.
    pub acceleration: [f64; N],
}

/// One quintic segment: per axis `p(tau) = k0 + k1 tau + ... + k5 tau^5`, `tau` in
/// `[0, duration_s]`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment<const N: usize> {
    start_s: f64,
    duration_s: f64,
    coefficients: [[f64; 6]; N],
}

impl<const N: usize> Segment<N> {
    const UNUSED: Self = Self {
        start_s: 0.0,
        duration_s: 0.0,
        coefficients: [[0.0; 6]; N],
    };
}

/// Boundary state of one axis at a waypoint.
#[derive(Debug, Clone, Copy)]
struct Knot {
    p: f64,
    v: f64,
    a: f64,
}

/// Coefficients `[k0..k5]` of the quintic matching position, velocity and acceleration at both
/// ends of a segment of length `t` (closed-form solution of the 6x6 boundary system).
fn quintic_coefficients(start: Knot, end: Knot, t: f64) -> [f64; 6] {
    let h = end.p - start.p;
    let (t2, t3) = (t * t, t * t * t);
    let (t4, t5) = (t3 * t, t3 * t2);
    [
        start.p,
        start.v,
        0.5 * start.a,
        (20.0 * h - (8.0 * end.v + 12.0 * start.v) * t - (3.0 * start.a - end.a) * t2) / (2.0 * t3),
        (-30.0 * h + (14.0 * end.v + 16.0 * start.v) * t + (3.0 * start.a - 2.0 * end.a) * t2)
            / (2.0 * t4),
        (12.0 * h - 6.0 * (end.v + start.v) * t + (end.a - start.a) * t2) / (2.0 * t5),
    ]
}

/// Evaluates eq. 3 (position, velocity, acceleration) of coefficients `k` at local time `tau`.
fn evaluate(k: &[f64; 6], tau: f64) -> (f64, f64, f64) {
    let p = k[0] + tau * (k[1] + tau * (k[2] + tau * (k[3] + tau * (k[4] + tau * k[5]))));
    let v = k[1] + tau * (2.0 * k[2] + tau * (3.0 * k[3] + tau * (4.0 * k[4] + tau * 5.0 * k[5])));
    let a = 2.0 * k[2] + tau * (6.0 * k[3] + tau * (12.0 * k[4] + tau * 20.0 * k[5]));
    (p, v, a)
}

/// A C2 quintic spline through timed waypoints in `N` dimensions (eq. 3 with the paper's
/// velocity/acceleration augmentation).
#[derive(Clone, PartialEq)]
pub struct QuinticSpline<const N: usize> {
    /// The first `segment_count` are the spline; the rest stay [`Segment::UNUSED`].
    segments: [Segment<N>; MAX_WAYPOINTS - 1],
    segment_count: usize,
    /// Last waypoint, returned exactly (at rest) from the end time on.
    last_position: [f64; N],
}

impl<const N: usize> std::fmt::Debug for QuinticSpline<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("QuinticSpline")
            .field("segments", &self.used_segments())
            .field("last_position", &self.last_position)
            .finish()
    }
}

impl<const N: usize> QuinticSpline<N> {
    /// Builds the spline through `positions[i]` at `times_s[i]`, starting with velocity
    /// `start_velocity` (per axis, per second) and ending at rest.
    pub fn through(
        times_s: &[f64],
        positions: &[[f64; N]],
        start_velocity: [f64; N],
    ) -> Result<Self, TrajectoryError> {
        let n = positions.len();
        if times_s.len() != n {
            return Err(TrajectoryError::LengthMismatch {
                times: times_s.len(),
                positions: n,
            });
        }
        if n < 2 {
            return Err(TrajectoryError::TooFewWaypoints { count: n });
        }
        if n > MAX_WAYPOINTS {
            return Err(TrajectoryError::TooManyWaypoints { count: n });
        }
        if start_velocity.iter().any(|v| !v.is_finite()) {
            return Err(TrajectoryError::NonFinite { index: 0 });
        }
        for (index, (t, p)) in times_s.iter().zip(positions).enumerate() {
            if !t.is_finite() || p.iter().any(|v| !v.is_finite()) {
                return Err(TrajectoryError::NonFinite { index });
            }
        }
        for index in 1..n {
            if times_s[index] <= times_s[index - 1] {
                return Err(TrajectoryError::NonIncreasingTime {
                    index,
                    time_s: times_s[index],
                    previous_s: times_s[index - 1],
                });
            }
        }
        // Augmentation: central differences at interior waypoints.
        let velocity_at = |i: usize, axis: usize| -> f64 {
            if i == 0 {
                start_velocity[axis]
            } else if i == n - 1 {
                0.0
            } else {
                (positions[i + 1][axis] - positions[i - 1][axis])
                    / (times_s[i + 1] - times_s[i - 1])
            }
        };
        let acceleration_at = |i: usize, axis: usize| -> f64 {
            if i == 0 || i == n - 1 {
                0.0
            } else {
                (velocity_at(i + 1, axis) - velocity_at(i - 1, axis))
                    / (times_s[i + 1] - times_s[i - 1])
            }
        };
        let knot = |i: usize, axis: usize| Knot {
            p: positions[i][axis],
            v: velocity_at(i, axis),
            a: acceleration_at(i, axis),
        };
        let mut segments = [Segment::UNUSED; MAX_WAYPOINTS - 1];
        for (i, segment) in segments.iter_mut().enumerate().take(n - 1) {
            let duration_s = times_s[i + 1] - times_s[i];
            *segment = Segment {
                start_s: times_s[i],
                duration_s,
                coefficients: std::array::from_fn(|axis| {
                    quintic_coefficients(knot(i, axis), knot(i + 1, axis), duration_s)
                }),
            };
        }
        Ok(Self {
            segments,
            segment_count: n - 1,
            last_position: positions[n - 1],
        })
    }

    fn used_segments(&self) -> &[Segment<N>] {
        &self.segments[..self.segment_count.min(MAX_WAYPOINTS - 1)]
    }

    /// Time of the first waypoint, s.
    pub fn start_s(&self) -> f64 {
        self.used_segments().first().map_or(0.0, |s| s.start_s)
    }

    /// Time of the last waypoint, s.
    pub fn end_s(&self) -> f64 {
        self.used_segments()
            .last()
            .map_or(0.0, |s| s.start_s + s.duration_s)
    }

    /// Number of segments (waypoints - 1).
    pub fn segment_count(&self) -> usize {
        self.used_segments().len()
    }

    /// Evaluates eq. 3 at time `t_s`. Before the first waypoint it returns the first waypoint
    /// (with the start velocity); after the last it returns the last waypoint at rest.
    /// Allocation-free; `O(log n)` segment lookup.
    pub fn sample(&self, t_s: f64) -> TrajectorySample<N> {
        let zero = TrajectorySample {
            position: [0.0; N],
            velocity: [0.0; N],
            acceleration: [0.0; N],
        };
        let segments = self.used_segments();
        let Some(last) = segments.last() else {
            return zero;
        };
        if t_s >= self.end_s() {
            return TrajectorySample {
                position: self.last_position,
                ..zero
            };
        }
        let t = if t_s.is_finite() {
            t_s.clamp(self.start_s(), self.end_s())
        } else {
            self.start_s()
        };
        let index = segments
            .partition_point(|s| s.start_s + s.duration_s < t)
            .min(segments.len() - 1);
        let segment = segments.get(index).unwrap_or(last);
        let tau = (t - segment.start_s).clamp(0.0, segment.duration_s);
        let mut out = zero;
        for axis in 0..N {
            let (p, v, a) = evaluate(&segment.coefficients[axis], tau);
            out.position[axis] = p;
            out.velocity[axis] = v;
            out.acceleration[axis] = a;
        }
        out
    }

    /// Position/velocity/acceleration at both ends of segment `index` (for continuity checks).
    #[cfg(test)]
    fn segment_ends(&self, index: usize) -> (TrajectorySample<N>, TrajectorySample<N>) {
        let s = &self.used_segments()[index];
        let at = |tau: f64| {
            let mut out = TrajectorySample {
                position: [0.0; N],
                velocity: [0.0; N],
                acceleration: [0.0; N],
            };
            for axis in 0..N {
                let (p, v, a) = evaluate(&s.coefficients[axis], tau);
                out.position[axis] = p;
                out.velocity[axis] = v;
                out.acceleration[axis] = a;
            }
            out
        };
        (at(0.0), at(s.duration_s))
    }
}

/// Reference state of the four joints at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointSample {
    /// Reference joint positions.
    pub position: JointPosition,
    /// Reference joint rates.
    pub velocity: JointVelocity,
    /// Reference joint accelerations `[m/s^2, rad/s^2, rad/s^2, rad/s^2]`.
    pub acceleration: [f64; 4],
}

/// Samples per segment used to find the peak rates during time scaling.
const PEAK_SAMPLES_PER_SEGMENT: usize = 32;
/// Target peak-over-limit ratio of the time scaling (margin for the sampled peak).
const TARGET_PEAK_RATIO: f64 = 0.995;
/// Shortest segment the time scaling produces, s.
pub const MIN_SEGMENT_S: f64 = 0.05;
/// Peak speed of a rest-to-rest quintic over its mean speed.
const QUINTIC_PEAK_OVER_MEAN: f64 = 1.875;
/// Iteration cap of the time scaling.
const MAX_SCALING_ITERATIONS: usize = 12;

/// A time-scaled quintic joint-space trajectory `[D, theta, phi, twist]` for one arm. Time runs
/// from 0 at the first waypoint.
#[derive(Debug, Clone, PartialEq)]
pub struct JointTrajectory {
    spline: QuinticSpline<4>,
    peak_ratio: f64,
}

impl JointTrajectory {
    /// Plans a trajectory through `waypoints` (the first is the current joint state) starting
    /// with joint rates `start_velocity`, timed so that every joint rate stays below
    /// `speed_fraction x params.rate_limits` and the end-effector speed below
    /// `speed_fraction x params.max_end_effector_speed_m_per_s`.
    ///
    /// The start velocity is clamped to the scaled rate limits (it is a measurement). Waypoints
    /// after the first must lie inside the joint limits.
    pub fn plan(
        params: &ArmParams,
        waypoints: &[JointPosition],
        start_velocity: &JointVelocity,
        speed_fraction: f64,
    ) -> Result<Self, TrajectoryError> {
        if !(speed_fraction > 0.0 && speed_fraction <= 1.0) {
            return Err(TrajectoryError::BadSpeedFraction {
                value: speed_fraction,
            });
        }
        if waypoints.len() < 2 {
            return Err(TrajectoryError::TooFewWaypoints {
                count: waypoints.len(),
            });
        }
        if waypoints.len() > MAX_WAYPOINTS {
            return Err(TrajectoryError::TooManyWaypoints {
                count: waypoints.len(),
            });
        }
        if !start_velocity.is_finite() {
            return Err(TrajectoryError::NonFinite { index: 0 });
        }
        for (index, w) in waypoints.iter().enumerate() {
            if !w.is_finite() {
                return Err(TrajectoryError::NonFinite { index });
            }
            if index > 0 && !params.position_limits.contains(w) {
                return Err(TrajectoryError::OutsideLimits {
                    index,
                    position: *w,
                });
            }
        }
        let rate_max: [f64; 4] = params.rate_limits.to_array().map(|v| v * speed_fraction);
        let speed_max = params.max_end_effector_speed_m_per_s * speed_fraction;
        let v0 = start_velocity.to_array();
        let start = std::array::from_fn(|i| v0[i].clamp(-rate_max[i], rate_max[i]));
        let n = waypoints.len();
        let mut positions_buffer = [[0.0; 4]; MAX_WAYPOINTS];
        for (position, waypoint) in positions_buffer.iter_mut().zip(waypoints) {
            *position = waypoint.to_array();
        }
        let positions = &positions_buffer[..n];

        // Initial durations: rest-to-rest quintic estimate per segment.
        let mut durations_buffer = [0.0; MAX_WAYPOINTS - 1];
        let durations = &mut durations_buffer[..n - 1];
        for ((duration, pair), wp) in durations
            .iter_mut()
            .zip(positions.windows(2))
            .zip(waypoints.windows(2))
        {
            let joint_time = (0..4)
                .map(|i| (pair[1][i] - pair[0][i]).abs() / rate_max[i])
                .fold(0.0, f64::max);
            let a = forward(&params.links, &wp[0]);
            let b = forward(&params.links, &wp[1]);
            let chord = (0..3).map(|i| (b[i] - a[i]).powi(2)).sum::<f64>().sqrt();
            *duration =
                (QUINTIC_PEAK_OVER_MEAN * joint_time.max(chord / speed_max)).max(MIN_SEGMENT_S);
        }
        let mut times_buffer = [0.0; MAX_WAYPOINTS];
        let times = &mut times_buffer[..n];

        let mut last_ratio = f64::INFINITY;
        let mut best: Option<(QuinticSpline<4>, f64)> = None;
        for _ in 0..MAX_SCALING_ITERATIONS {
            for i in 1..times.len() {
                times[i] = times[i - 1] + durations[i - 1];
            }
            let spline = QuinticSpline::through(times, positions, start)?;
            let ratio = peak_ratio(params, &spline, &rate_max, speed_max);
            last_ratio = ratio;
            let all_min = durations.iter().all(|&d| d <= MIN_SEGMENT_S);
            let feasible = ratio <= 1.0;
            let tight = ratio >= 0.97 * TARGET_PEAK_RATIO;
            if feasible && (tight || all_min || ratio <= 0.0) {
                return Ok(Self {
                    spline,
                    peak_ratio: ratio,
                });
            }
            if feasible && best.as_ref().is_none_or(|(_, r)| ratio > *r) {
                best = Some((spline, ratio));
            }
            let scale = ratio / TARGET_PEAK_RATIO;
            for d in durations.iter_mut() {
                *d = (*d * scale).max(MIN_SEGMENT_S);
            }
        }
        match best {
            Some((spline, peak_ratio)) => Ok(Self { spline, peak_ratio }),
            None => Err(TrajectoryError::LimitsNotMet {
                ratio: last_ratio,
                iterations: MAX_SCALING_ITERATIONS,
            }),
        }
    }

    /// A trajectory that holds `position` (zero rates) for `duration_s` (at least
    /// [`MIN_SEGMENT_S`]).
    pub fn hold(position: &JointPosition, duration_s: f64) -> Result<Self, TrajectoryError> {
        let p = position.to_array();
        let spline =
            QuinticSpline::through(&[0.0, duration_s.max(MIN_SEGMENT_S)], &[p, p], [0.0; 4])?;
        Ok(Self {
            spline,
            peak_ratio: 0.0,
        })
    }

    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.spline.end_s()
    }

    /// Sampled peak of rate/limit reached by this trajectory (at most 1).
    pub fn peak_ratio(&self) -> f64 {
        self.peak_ratio
    }

    /// Final joint position.
    pub fn end_position(&self) -> JointPosition {
        JointPosition::from_array(self.spline.sample(self.duration_s()).position)
    }

    /// Reference joint state at `t_s` seconds after the start (clamped to the ends).
    pub fn sample(&self, t_s: f64) -> JointSample {
        let s = self.spline.sample(t_s);
        JointSample {
            position: JointPosition::from_array(s.position),
            velocity: JointVelocity::from_array(s.velocity),
            acceleration: s.acceleration,
        }
    }

    /// The underlying spline.
    pub fn spline(&self) -> &QuinticSpline<4> {
        &self.spline
    }
}

/// Largest ratio of |joint rate| / limit and |end-effector speed| / limit over samples.
fn peak_ratio(
    params: &ArmParams,
    spline: &QuinticSpline<4>,
    rate_max: &[f64; 4],
    speed_max: f64,
) -> f64 {
    let mut peak: f64 = 0.0;
    for segment in spline.used_segments() {
        for k in 0..=PEAK_SAMPLES_PER_SEGMENT {
            let tau = segment.duration_s * k as f64 / PEAK_SAMPLES_PER_SEGMENT as f64;
            let mut q = [0.0; 4];
            let mut qd = [0.0; 4];
            for axis in 0..4 {
                let (p, v, _) = evaluate(&segment.coefficients[axis], tau);
                q[axis] = p;
                qd[axis] = v;
                peak = peak.max(v.abs() / rate_max[axis]);
            }
            let v_ee = end_effector_velocity(
                &params.links,
                &JointPosition::from_array(q),
                &JointVelocity::from_array(qd),
            );
            let speed = v_ee.iter().map(|c| c * c).sum::<f64>().sqrt();
            peak = peak.max(speed / speed_max);
        }
    }
    peak
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // axis-indexed loops over small fixed arrays
mod tests {
    use super::*;
    use harvest_robot_model::kinematics::inverse;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn rest_to_rest_segment_known_answer() {
        // Minimum-jerk profile: midpoint at half the distance, peak speed 1.875 h / T.
        let s = QuinticSpline::<1>::through(&[0.0, 2.0], &[[1.0], [3.0]], [0.0]).unwrap();
        let mid = s.sample(1.0);
        assert!(close(mid.position[0], 2.0, 1e-12));
        assert!(close(mid.velocity[0], 1.875 * 2.0 / 2.0, 1e-12));
        assert!(close(mid.acceleration[0], 0.0, 1e-12));
        let q = s.sample(0.5);
        // 10 s^3 - 15 s^4 + 6 s^5 at s = 0.25, times h = 2.
        let frac: f64 = 10.0 * 0.25f64.powi(3) - 15.0 * 0.25f64.powi(4) + 6.0 * 0.25f64.powi(5);
        assert!(close(q.position[0], 1.0 + 2.0 * frac, 1e-12));
    }

    fn random_spline(rng: &mut SmallRng, n: usize) -> (Vec<f64>, Vec<[f64; 3]>, [f64; 3]) {
        let mut times = vec![0.0];
        for _ in 1..n {
            let last = *times.last().unwrap();
            times.push(last + rng.random_range(0.1..1.0));
        }
        let positions = (0..n)
            .map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)))
            .collect();
        let v0 = std::array::from_fn(|_| rng.random_range(-0.5..0.5));
        (times, positions, v0)
    }

    #[test]
    fn passes_through_waypoints_and_meets_boundary_conditions() {
        let mut rng = SmallRng::seed_from_u64(1);
        for n in 2..16 {
            let (times, positions, v0) = random_spline(&mut rng, n);
            let s = QuinticSpline::<3>::through(&times, &positions, v0).unwrap();
            for (t, p) in times.iter().zip(&positions) {
                let at = s.sample(*t);
                for axis in 0..3 {
                    assert!(close(at.position[axis], p[axis], 1e-9));
                }
            }
            let start = s.sample(0.0);
            let end = s.sample(*times.last().unwrap());
            for axis in 0..3 {
                assert!(close(start.velocity[axis], v0[axis], 1e-9));
                assert!(close(start.acceleration[axis], 0.0, 1e-9));
                assert!(close(end.velocity[axis], 0.0, 1e-9));
                assert!(close(end.acceleration[axis], 0.0, 1e-9));
            }
            // Beyond the ends: clamped.
            assert_eq!(s.sample(-1.0).position, positions[0]);
            assert_eq!(s.sample(1e9).velocity, [0.0; 3]);
        }
    }

    #[test]
    fn velocity_and_acceleration_are_continuous_and_augmented_as_in_the_paper() {
        let mut rng = SmallRng::seed_from_u64(2);
        for n in 3..16 {
            let (times, positions, v0) = random_spline(&mut rng, n);
            let s = QuinticSpline::<3>::through(&times, &positions, v0).unwrap();
            for i in 1..n - 1 {
                let (_, left) = s.segment_ends(i - 1);
                let (right, _) = s.segment_ends(i);
                for axis in 0..3 {
                    assert!(close(left.position[axis], right.position[axis], 1e-9));
                    assert!(close(left.velocity[axis], right.velocity[axis], 1e-9));
                    assert!(close(
                        left.acceleration[axis],
                        right.acceleration[axis],
                        1e-8
                    ));
                    let central = (positions[i + 1][axis] - positions[i - 1][axis])
                        / (times[i + 1] - times[i - 1]);
                    assert!(close(right.velocity[axis], central, 1e-9));
                }
            }
        }
    }

    #[test]
    fn velocity_and_acceleration_are_derivatives_of_position() {
        let mut rng = SmallRng::seed_from_u64(4);
        let (times, positions, v0) = random_spline(&mut rng, 6);
        let s = QuinticSpline::<3>::through(&times, &positions, v0).unwrap();
        let h = 1e-6;
        let end = *times.last().unwrap();
        for k in 1..200 {
            let t = end * k as f64 / 200.0;
            let (a, b, c) = (s.sample(t - h), s.sample(t), s.sample(t + h));
            for axis in 0..3 {
                let v_fd = (c.position[axis] - a.position[axis]) / (2.0 * h);
                let a_fd = (c.velocity[axis] - a.velocity[axis]) / (2.0 * h);
                assert!(close(v_fd, b.velocity[axis], 1e-5));
                assert!(close(a_fd, b.acceleration[axis], 1e-4));
            }
        }
    }

    #[test]
    fn rejects_bad_inputs() {
        assert!(matches!(
            QuinticSpline::<1>::through(&[0.0], &[[0.0]], [0.0]),
            Err(TrajectoryError::TooFewWaypoints { count: 1 })
        ));
        assert!(matches!(
            QuinticSpline::<1>::through(&[0.0, 1.0], &[[0.0]], [0.0]),
            Err(TrajectoryError::LengthMismatch { .. })
        ));
        assert!(matches!(
            QuinticSpline::<1>::through(&[0.0, 1.0, 1.0], &[[0.0], [1.0], [2.0]], [0.0]),
            Err(TrajectoryError::NonIncreasingTime { index: 2, .. })
        ));
        assert!(matches!(
            QuinticSpline::<1>::through(&[0.0, 1.0], &[[0.0], [f64::NAN]], [0.0]),
            Err(TrajectoryError::NonFinite { index: 1 })
        ));
        let p = ArmParams::arm1();
        let home = p.home;
        let outside = JointPosition::from_array([0.9, 0.0, 0.0, 0.0]);
        assert!(matches!(
            JointTrajectory::plan(&p, &[home, outside], &JointVelocity::ZERO, 0.6),
            Err(TrajectoryError::OutsideLimits { index: 1, .. })
        ));
        assert!(matches!(
            JointTrajectory::plan(&p, &[home, home], &JointVelocity::ZERO, 1.5),
            Err(TrajectoryError::BadSpeedFraction { .. })
        ));
    }

    /// Independent dense check of the limits a trajectory respects; returns the peak ratio.
    fn dense_peak(params: &ArmParams, traj: &JointTrajectory, fraction: f64) -> f64 {
        let rate = params.rate_limits.to_array();
        let mut peak: f64 = 0.0;
        let steps = 5000;
        for k in 0..=steps {
            let s = traj.sample(traj.duration_s() * k as f64 / steps as f64);
            let v = s.velocity.to_array();
            for i in 0..4 {
                peak = peak.max(v[i].abs() / (rate[i] * fraction));
            }
            let ee = end_effector_velocity(&params.links, &s.position, &s.velocity);
            let speed = ee.iter().map(|c| c * c).sum::<f64>().sqrt();
            peak = peak.max(speed / (params.max_end_effector_speed_m_per_s * fraction));
        }
        peak
    }

    #[test]
    fn time_scaling_respects_and_nearly_reaches_the_limits() {
        let mut rng = SmallRng::seed_from_u64(9);
        for params in [ArmParams::arm1(), ArmParams::arm2()] {
            for fraction in [0.3, 0.6, 1.0] {
                for n in 2..8 {
                    let lo = params.position_limits.min.to_array();
                    let hi = params.position_limits.max.to_array();
                    let waypoints: Vec<JointPosition> = (0..n)
                        .map(|_| {
                            JointPosition::from_array(std::array::from_fn(|i| {
                                rng.random_range(lo[i]..=hi[i]) * if i == 3 { 0.2 } else { 1.0 }
                            }))
                        })
                        .collect();
                    let v0 = JointVelocity::from_array([0.1, -0.05, 0.05, 0.0]);
                    let traj = JointTrajectory::plan(&params, &waypoints, &v0, fraction).unwrap();
                    let peak = dense_peak(&params, &traj, fraction);
                    assert!(peak <= 1.005, "peak {peak} exceeds the limit");
                    assert!(peak >= 0.9, "peak {peak}: scaling is too conservative");
                    let end = traj.end_position().to_array();
                    let goal = waypoints.last().unwrap().to_array();
                    for i in 0..4 {
                        assert!(close(end[i], goal[i], 1e-9));
                    }
                }
            }
        }
    }

    #[test]
    fn straight_ahead_move_is_limited_by_the_end_effector_speed() {
        // Pure D motion of 0.5 m at fraction 0.6: peak speed 0.6 * 0.7748, duration
        // 1.875 * 0.5 / (0.6 * 0.7748) / 0.995.
        let p = ArmParams::arm1();
        let goal = JointPosition { d_m: 0.5, ..p.home };
        let traj = JointTrajectory::plan(&p, &[p.home, goal], &JointVelocity::ZERO, 0.6).unwrap();
        let expected = 1.875 * 0.5 / (0.6 * 0.7748) / TARGET_PEAK_RATIO;
        assert!(
            close(traj.duration_s(), expected, 0.01 * expected),
            "{}",
            traj.duration_s()
        );
        let mid = traj.sample(traj.duration_s() / 2.0);
        assert!(close(mid.position.d_m, 0.25, 1e-9));
    }

    #[test]
    fn hold_stays_put() {
        let q = JointPosition::from_array([0.1, 0.2, -0.1, 0.3]);
        let h = JointTrajectory::hold(&q, 0.5).unwrap();
        assert_eq!(h.sample(0.25).position, q);
        assert_eq!(h.sample(0.25).velocity, JointVelocity::ZERO);
        assert!(close(h.duration_s(), 0.5, 1e-12));
    }

    #[test]
    fn plan_through_ik_waypoints() {
        let p = ArmParams::arm2();
        let targets = [[1.2, -0.15, 0.3], [1.35, -0.05, 0.4], [1.4, -0.2, 0.25]];
        let mut waypoints = vec![p.home];
        for t in targets {
            waypoints.push(inverse(&p, t).unwrap());
        }
        let traj = JointTrajectory::plan(&p, &waypoints, &JointVelocity::ZERO, 0.6).unwrap();
        assert_eq!(traj.spline().segment_count(), 3);
        let end = harvest_robot_model::kinematics::forward(&p.links, &traj.end_position());
        for i in 0..3 {
            assert!(close(end[i], targets[2][i], 1e-9));
        }
    }

    /// Reports (does not assert) the generation time for 15 waypoints; the paper quotes
    /// < 0.1 s. Run: `cargo test -p harvest-arm --release -- --ignored --nocapture
    /// report_generation_time`.
    #[test]
    #[ignore = "performance report, run explicitly"]
    fn report_generation_time() {
        let p = ArmParams::arm1();
        let mut rng = SmallRng::seed_from_u64(15);
        let lo = p.position_limits.min.to_array();
        let hi = p.position_limits.max.to_array();
        let waypoints: Vec<JointPosition> = (0..15)
            .map(|_| {
                JointPosition::from_array(std::array::from_fn(|i| {
                    rng.random_range(lo[i]..=hi[i]) * if i == 3 { 0.1 } else { 1.0 }
                }))
            })
            .collect();
        let positions: Vec<[f64; 4]> = waypoints.iter().map(|w| w.to_array()).collect();
        let times: Vec<f64> = (0..15).map(|i| i as f64 * 0.4).collect();
        let repeats = 2000;
        let t0 = std::time::Instant::now();
        for _ in 0..repeats {
            std::hint::black_box(QuinticSpline::through(&times, &positions, [0.0; 4]).unwrap());
        }
        let spline_us = t0.elapsed().as_secs_f64() * 1e6 / repeats as f64;
        let t0 = std::time::Instant::now();
        for _ in 0..repeats {
            std::hint::black_box(
                JointTrajectory::plan(&p, &waypoints, &JointVelocity::ZERO, 0.6).unwrap(),
            );
        }
        let plan_us = t0.elapsed().as_secs_f64() * 1e6 / repeats as f64;
        let t0 = std::time::Instant::now();
        let traj = JointTrajectory::plan(&p, &waypoints, &JointVelocity::ZERO, 0.6).unwrap();
        let mut acc = 0.0;
        let samples = 100_000;
        for k in 0..samples {
            acc += traj
                .sample(traj.duration_s() * k as f64 / samples as f64)
                .position
                .d_m;
        }
        std::hint::black_box(acc);
        let sample_ns = t0.elapsed().as_secs_f64() * 1e9 / samples as f64;
        println!(
            "15 waypoints: spline fit {spline_us:.2} us, time-scaled plan {plan_us:.1} us, \
             sample {sample_ns:.0} ns (paper: < 0.1 s)"
        );
    }
}
