//! Inter-arm clearance check run before an arm starts a motion ([dual-arm sec. 3.3]: each
//! arm checks the other arm's status before moving toward its apple).
//!
//! Model (choice; the paper gives no geometry for the check): each arm body is the straight
//! tube axis from its yaw pivot to its end-effector ([`crate::kinematics::yaw_pivot`] to
//! [`crate::kinematics::forward`]). A motion sweeps a sequence of such segments, sampled along
//! the joint path. Two swept paths are compatible when every pair of segments is at least the
//! clearance apart (axis-to-axis distance, so the clearance must cover both tube radii, both
//! soft cups and a margin). Timing is ignored, which is conservative.

use crate::joint::JointPosition;
use crate::kinematics::{forward, yaw_pivot};
use crate::params::LinkParams;

/// Default axis-to-axis clearance between the two tube bodies, m (choice: two tube/cup radii of
/// about 4 cm each plus 7 cm margin; below the 0.22 m spacing of the two arms at home).
pub const DEFAULT_CLEARANCE_M: f64 = 0.15;

/// Capacity of a [`SweptPath`] (segments).
pub const SWEPT_PATH_CAPACITY: usize = 32;

/// The tube body of one arm at one instant: the segment from the yaw pivot to the
/// end-effector, robot frame, m.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TubeSegment {
    /// Yaw pivot, m.
    pub pivot_m: [f64; 3],
    /// End-effector, m.
    pub tip_m: [f64; 3],
}

impl TubeSegment {
    /// The tube body of an arm with `links` at joints `q`.
    pub fn at(links: &LinkParams, q: &JointPosition) -> Self {
        Self {
            pivot_m: yaw_pivot(links, q),
            tip_m: forward(links, q),
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn lerp(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * s,
        a[1] + (b[1] - a[1]) * s,
        a[2] + (b[2] - a[2]) * s,
    ]
}

/// Shortest distance between two segments, m (closest-point parameters clamped to the
/// segments; handles degenerate and parallel segments).
pub fn segment_distance_m(a: &TubeSegment, b: &TubeSegment) -> f64 {
    let d1 = sub(a.tip_m, a.pivot_m);
    let d2 = sub(b.tip_m, b.pivot_m);
    let r = sub(a.pivot_m, b.pivot_m);
    let aa = dot(d1, d1);
    let ee = dot(d2, d2);
    let f = dot(d2, r);
    const EPS: f64 = 1e-12;
    let (s, t) = if aa <= EPS && ee <= EPS {
        (0.0, 0.0)
    } else if aa <= EPS {
        (0.0, (f / ee).clamp(0.0, 1.0))
    } else {
        let c = dot(d1, r);
        if ee <= EPS {
            ((-c / aa).clamp(0.0, 1.0), 0.0)
        } else {
            let bb = dot(d1, d2);
            let denom = aa * ee - bb * bb;
            let mut s = if denom > EPS {
                ((bb * f - c * ee) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (bb * s + f) / ee;
            if t < 0.0 {
                t = 0.0;
                s = (-c / aa).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((bb - c) / aa).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    let pa = lerp(a.pivot_m, a.tip_m, s);
    let pb = lerp(b.pivot_m, b.tip_m, t);
    let d = sub(pa, pb);
    dot(d, d).sqrt()
}

/// Tube segments swept by one arm over a planned or assumed motion; fixed capacity, no
/// allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweptPath {
    segments: [TubeSegment; SWEPT_PATH_CAPACITY],
    len: usize,
}

impl Default for SweptPath {
    fn default() -> Self {
        Self::new()
    }
}

impl SweptPath {
    /// An empty path (compatible with everything).
    pub fn new() -> Self {
        Self {
            segments: [TubeSegment::default(); SWEPT_PATH_CAPACITY],
            len: 0,
        }
    }

    /// Adds the tube body at `q`; returns false (and drops it) when the path is full.
    pub fn push(&mut self, links: &LinkParams, q: &JointPosition) -> bool {
        match self.segments.get_mut(self.len) {
            Some(slot) => {
                *slot = TubeSegment::at(links, q);
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// Adds `samples` + 1 tube bodies along the straight joint-space line from `from` to `to`
    /// (both included); returns false if the capacity ran out.
    pub fn push_joint_line(
        &mut self,
        links: &LinkParams,
        from: &JointPosition,
        to: &JointPosition,
        samples: usize,
    ) -> bool {
        let (a, b) = (from.to_array(), to.to_array());
        let n = samples.max(1);
        (0..=n).all(|k| {
            let s = k as f64 / n as f64;
            let q = JointPosition::from_array(std::array::from_fn(|i| a[i] + (b[i] - a[i]) * s));
            self.push(links, &q)
        })
    }

    /// Number of stored segments.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no segment is stored.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The stored segments.
    pub fn segments(&self) -> &[TubeSegment] {
        self.segments.get(..self.len).unwrap_or(&[])
    }

    /// Smallest distance between any segment of `self` and any of `other`, m (infinite when
    /// either is empty).
    pub fn min_distance_m(&self, other: &SweptPath) -> f64 {
        let mut best = f64::INFINITY;
        for a in self.segments() {
            for b in other.segments() {
                best = best.min(segment_distance_m(a, b));
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::ArmParams;

    fn seg(a: [f64; 3], b: [f64; 3]) -> TubeSegment {
        TubeSegment {
            pivot_m: a,
            tip_m: b,
        }
    }

    #[test]
    fn segment_distance_known_answers() {
        // Crossing skew lines 1 m apart.
        let a = seg([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let b = seg([0.0, -1.0, 1.0], [0.0, 1.0, 1.0]);
        assert!((segment_distance_m(&a, &b) - 1.0).abs() < 1e-12);
        // Parallel, offset 0.3 m, overlapping.
        let c = seg([0.5, 0.3, 0.0], [2.0, 0.3, 0.0]);
        assert!((segment_distance_m(&a, &c) - 0.3).abs() < 1e-12);
        // Collinear, gap of 0.5 m between the ends.
        let d = seg([1.5, 0.0, 0.0], [3.0, 0.0, 0.0]);
        assert!((segment_distance_m(&a, &d) - 0.5).abs() < 1e-12);
        // Point to segment.
        let p = seg([0.0, 0.4, 0.0], [0.0, 0.4, 0.0]);
        assert!((segment_distance_m(&a, &p) - 0.4).abs() < 1e-12);
        assert!((segment_distance_m(&p, &a) - 0.4).abs() < 1e-12);
        // End-point closest: segments in a T not touching.
        let e = seg([2.0, -1.0, 0.0], [2.0, 1.0, 0.0]);
        assert!((segment_distance_m(&a, &e) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn segment_distance_is_symmetric_and_matches_brute_force() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        for _ in 0..300 {
            let a = seg([next(), next(), next()], [next(), next(), next()]);
            let b = seg([next(), next(), next()], [next(), next(), next()]);
            let d = segment_distance_m(&a, &b);
            assert!((d - segment_distance_m(&b, &a)).abs() < 1e-9);
            let mut brute = f64::INFINITY;
            for i in 0..=200 {
                for j in 0..=200 {
                    let pa = lerp(a.pivot_m, a.tip_m, i as f64 / 200.0);
                    let pb = lerp(b.pivot_m, b.tip_m, j as f64 / 200.0);
                    let v = sub(pa, pb);
                    brute = brute.min(dot(v, v).sqrt());
                }
            }
            assert!(d <= brute + 1e-12 && brute - d < 0.02, "{d} vs {brute}");
        }
    }

    #[test]
    fn arms_at_home_are_clear_and_crossed_arms_are_not() {
        let a1 = ArmParams::arm1();
        let a2 = ArmParams::arm2();
        let mut p1 = SweptPath::new();
        let mut p2 = SweptPath::new();
        p1.push(&a1.links, &a1.home);
        p2.push(&a2.links, &a2.home);
        let home_gap = p1.min_distance_m(&p2);
        assert!(home_gap > DEFAULT_CLEARANCE_M, "home gap {home_gap}");
        assert!(home_gap < 0.23);
        // Arm 1 yawing fully right and arm 2 fully left at the same height cross.
        let q1 = JointPosition::from_array([0.2, 0.1, a1.position_limits.max.phi_rad, 0.0]);
        let q2 = JointPosition::from_array([0.2, 0.1, a2.position_limits.min.phi_rad, 0.0]);
        let mut s1 = SweptPath::new();
        assert!(s1.push_joint_line(&a1.links, &a1.home, &q1, 8));
        let mut s2 = SweptPath::new();
        assert!(s2.push_joint_line(&a2.links, &a2.home, &q2, 8));
        assert!(s1.min_distance_m(&s2) < DEFAULT_CLEARANCE_M);
        assert_eq!(s1.len(), 9);
        assert_eq!(SweptPath::new().min_distance_m(&s1), f64::INFINITY);
    }

    #[test]
    fn capacity_is_enforced() {
        let a1 = ArmParams::arm1();
        let mut s = SweptPath::new();
        assert!(!s.push_joint_line(&a1.links, &a1.home, &a1.home, SWEPT_PATH_CAPACITY + 5));
        assert_eq!(s.len(), SWEPT_PATH_CAPACITY);
    }
}
