//! Apple assignment to the two arms: [dual-arm Algorithm 1] (sec. 3.3, Fig. 8).
//!
//! 1. Each apple is classified by reachability: arm 1 only, arm 2 only, both, or neither (the
//!    paper's `dist_i(p) < ∞`). Reachability is a caller-provided predicate so this crate does
//!    not depend on the arm kinematics.
//! 2. Apples reachable by both arms are sorted along the lateral axis, from arm 1's side to arm
//!    2's side, and handed to arm 1 until arm 1 holds half of all reachable apples; the rest go
//!    to arm 2. This split keeps the two arms on their own sides (no crossing).
//! 3. Each arm's list is sorted by increasing depth into the canopy, so the outer apples are
//!    picked before the arm has to reach past them.
//!
//! Two readings of the pseudo-code are made explicit (POLICY.md): apples reachable by neither
//! arm are discarded (the pseudo-code's `else` branch would put them in the shared set, the text
//! discards them), and the split stops once `2 |P1| >= n` (the pseudo-code's `|P1| <= n/2` test
//! hands arm 1 one apple more than half).

use harvest_robot_model::ArmId;
use serde::{Deserialize, Serialize};
use std::cmp::Ordering;
use thiserror::Error;

/// Identifier of one apple, stable across detection sets (see [`crate::replan`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct AppleId(pub u32);

/// One apple to pick: its id and its position in the assignment frame, metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Apple {
    /// Stable identifier.
    pub id: AppleId,
    /// Position in the frame described by [`AssignmentFrame`], m.
    pub position_m: [f64; 3],
}

/// A coordinate axis of the assignment frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Axis {
    /// First coordinate.
    X,
    /// Second coordinate.
    Y,
    /// Third coordinate.
    Z,
}

impl Axis {
    const fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// On which side of the lateral axis arm 1 sits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum LateralSide {
    /// Arm 1 is towards positive lateral coordinates.
    Positive,
    /// Arm 1 is towards negative lateral coordinates.
    Negative,
}

/// How to read apple positions: which axis is lateral (splits the shared region), which axis
/// is depth into the canopy (orders each arm's queue), and where arm 1 is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AssignmentFrame {
    /// Axis along which the two arms sit side by side.
    pub lateral_axis: Axis,
    /// Axis pointing into the canopy.
    pub depth_axis: Axis,
    /// Side of the lateral axis where arm 1 is.
    pub arm1_side: LateralSide,
}

impl AssignmentFrame {
    /// The robot frame of eq. 1 as the arm crate reads Table 1: x forward into the canopy, y to
    /// the left with arm 1 on the +y side, z up.
    pub const ROBOT: AssignmentFrame = AssignmentFrame {
        lateral_axis: Axis::Y,
        depth_axis: Axis::X,
        arm1_side: LateralSide::Positive,
    };

    /// The frame Algorithm 1 is written in (camera-like: depth along z, arm 1 towards small y).
    pub const PAPER_ALGORITHM_1: AssignmentFrame = AssignmentFrame {
        lateral_axis: Axis::Y,
        depth_axis: Axis::Z,
        arm1_side: LateralSide::Negative,
    };

    /// Depth of a point into the canopy, m.
    pub const fn depth_m(&self, position_m: &[f64; 3]) -> f64 {
        position_m[self.depth_axis.index()]
    }

    /// Lateral coordinate measured from arm 2's side towards arm 1's side, m: the larger, the
    /// closer to arm 1.
    pub const fn towards_arm1_m(&self, position_m: &[f64; 3]) -> f64 {
        let lateral = position_m[self.lateral_axis.index()];
        match self.arm1_side {
            LateralSide::Positive => lateral,
            LateralSide::Negative => -lateral,
        }
    }
}

impl Default for AssignmentFrame {
    fn default() -> Self {
        AssignmentFrame::ROBOT
    }
}

/// The output of Algorithm 1.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Assignment {
    /// Arm 1's queue, shallowest first.
    pub arm1: Vec<Apple>,
    /// Arm 2's queue, shallowest first.
    pub arm2: Vec<Apple>,
    /// Apples neither arm can reach, in input order.
    pub unreachable: Vec<Apple>,
}

impl Assignment {
    /// An empty assignment with room for `apples` in each list.
    pub fn with_capacity(apples: usize) -> Self {
        Self {
            arm1: Vec::with_capacity(apples),
            arm2: Vec::with_capacity(apples),
            unreachable: Vec::with_capacity(apples),
        }
    }

    /// The queue of `arm`, shallowest first.
    pub fn queue(&self, arm: ArmId) -> &[Apple] {
        match arm {
            ArmId::Arm1 => &self.arm1,
            ArmId::Arm2 => &self.arm2,
        }
    }
}

/// An input Algorithm 1 cannot place.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum AssignError {
    /// A position has a NaN or infinite coordinate.
    #[error("apple {id:?} has a non-finite position {position_m:?} m")]
    NonFinitePosition {
        /// The apple.
        id: AppleId,
        /// Its position.
        position_m: [f64; 3],
    },
}

/// Algorithm 1: split `apples` between the two arms. `reachable(arm, position_m)` tells whether
/// `arm` can reach a point (the paper's `dist_arm(p) < ∞`). Deterministic: ties are broken by
/// apple id.
pub fn assign_apples<F>(
    apples: &[Apple],
    frame: &AssignmentFrame,
    reachable: F,
) -> Result<Assignment, AssignError>
where
    F: Fn(ArmId, &[f64; 3]) -> bool,
{
    assign_apples_with_held(apples, frame, [0, 0], reachable)
}

/// Algorithm 1 run again while the arms work: `held[i]` apples are already in arm `i`'s hands
/// (attempts in progress, indexed by [`ArmId::index`]) and count towards its half in the split
/// of lines 12-17. Over a whole harvest this keeps the paper's split (each arm ends up with half
/// of the apples it was given, counting those it picked since), and at the end it gives the last
/// shared apple to the arm that is free rather than always to arm 1: re-planned over the waiting
/// apples only, the split would hand arm 1 the odd apple while it is still busy and leave arm 2
/// idle.
pub fn assign_apples_with_held<F>(
    apples: &[Apple],
    frame: &AssignmentFrame,
    held: [usize; 2],
    reachable: F,
) -> Result<Assignment, AssignError>
where
    F: Fn(ArmId, &[f64; 3]) -> bool,
{
    let mut out = Assignment::default();
    assign_apples_into(apples, frame, held, reachable, &mut out, &mut Vec::new())?;
    Ok(out)
}

/// [`assign_apples_with_held`] into `out` (cleared first), with `shared` as scratch: no
/// allocation once the vectors have the capacity (the vacuum supervisor re-plans inside its
/// 200 Hz tick). On error `out` holds a partial assignment.
pub fn assign_apples_into<F>(
    apples: &[Apple],
    frame: &AssignmentFrame,
    held: [usize; 2],
    reachable: F,
    out: &mut Assignment,
    shared: &mut Vec<Apple>,
) -> Result<(), AssignError>
where
    F: Fn(ArmId, &[f64; 3]) -> bool,
{
    out.arm1.clear();
    out.arm2.clear();
    out.unreachable.clear();
    shared.clear();
    // Lines 1-10: reachability classes.
    for apple in apples {
        if apple.position_m.iter().any(|c| !c.is_finite()) {
            return Err(AssignError::NonFinitePosition {
                id: apple.id,
                position_m: apple.position_m,
            });
        }
        let by1 = reachable(ArmId::Arm1, &apple.position_m);
        let by2 = reachable(ArmId::Arm2, &apple.position_m);
        match (by1, by2) {
            (true, false) => out.arm1.push(*apple),
            (false, true) => out.arm2.push(*apple),
            (true, true) => shared.push(*apple),
            (false, false) => out.unreachable.push(*apple),
        }
    }
    let reachable_count = out.arm1.len() + out.arm2.len() + shared.len() + held[0] + held[1];
    // Line 11: shared apples from arm 1's side to arm 2's side. Ids are unique, so the order is
    // total and the in-place (unstable, allocation-free) sort is deterministic.
    shared.sort_unstable_by(|a, b| {
        frame
            .towards_arm1_m(&b.position_m)
            .total_cmp(&frame.towards_arm1_m(&a.position_m))
            .then(a.id.cmp(&b.id))
    });
    // Lines 12-17: arm 1 takes from its side until it holds half of the reachable apples.
    let mut rest = shared.iter().copied();
    while 2 * (out.arm1.len() + held[0]) < reachable_count {
        match rest.next() {
            Some(apple) => out.arm1.push(apple),
            None => break,
        }
    }
    out.arm2.extend(rest);
    // Line 18: shallowest first.
    let by_depth = |a: &Apple, b: &Apple| -> Ordering {
        frame
            .depth_m(&a.position_m)
            .total_cmp(&frame.depth_m(&b.position_m))
            .then(a.id.cmp(&b.id))
    };
    out.arm1.sort_unstable_by(by_depth);
    out.arm2.sort_unstable_by(by_depth);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// Robot frame: arm 1 reaches y >= -0.1, arm 2 reaches y <= 0.1, nothing deeper than 1 m.
    fn overlap_reach(arm: ArmId, p: &[f64; 3]) -> bool {
        let lateral_ok = match arm {
            ArmId::Arm1 => p[1] >= -0.1,
            ArmId::Arm2 => p[1] <= 0.1,
        };
        lateral_ok && p[0] <= 1.0
    }

    fn apple(id: u32, x: f64, y: f64) -> Apple {
        Apple {
            id: AppleId(id),
            position_m: [x, y, 0.5],
        }
    }

    fn ids(list: &[Apple]) -> Vec<u32> {
        list.iter().map(|a| a.id.0).collect()
    }

    #[test]
    fn known_answer_on_a_small_scene() {
        let apples = [
            apple(0, 0.6, 0.3),   // arm 1 only
            apple(1, 0.5, -0.3),  // arm 2 only
            apple(2, 0.7, 0.05),  // shared, arm 1 side
            apple(3, 0.4, 0.0),   // shared, middle
            apple(4, 0.8, -0.05), // shared, arm 2 side
            apple(5, 1.3, 0.0),   // too deep: unreachable
            apple(6, 0.3, 0.08),  // shared, furthest on arm 1 side
        ];
        let a = assign_apples(&apples, &AssignmentFrame::ROBOT, overlap_reach).expect("finite");
        // 6 reachable: arm 1 holds {0} + shared by lateral order 6 (0.08), 2 (0.05) = 3.
        assert_eq!(ids(&a.arm1), vec![6, 0, 2]); // by depth 0.3, 0.6, 0.7
        assert_eq!(ids(&a.arm2), vec![3, 1, 4]); // by depth 0.4, 0.5, 0.8
        assert_eq!(ids(&a.unreachable), vec![5]);
    }

    #[test]
    fn apples_in_hand_count_towards_each_arm_half() {
        let apples = [
            apple(2, 0.7, 0.05),
            apple(3, 0.4, 0.0),
            apple(4, 0.8, -0.05),
        ];
        // Nothing in hand: arm 1 takes two of the three shared apples from its side (queued by
        // depth).
        let free = assign_apples_with_held(&apples, &AssignmentFrame::ROBOT, [0, 0], overlap_reach)
            .expect("finite");
        assert_eq!((ids(&free.arm1), ids(&free.arm2)), (vec![3, 2], vec![4]));
        // Arm 1 busy with one apple, arm 2 free: of 4 apples in all, arm 1 holds 2 with only
        // one more from the queue; the odd shared apple goes to the free arm.
        let busy = assign_apples_with_held(&apples, &AssignmentFrame::ROBOT, [1, 0], overlap_reach)
            .expect("finite");
        assert_eq!((ids(&busy.arm1), ids(&busy.arm2)), (vec![2], vec![3, 4]));
        let one = [apple(7, 0.6, 0.0)];
        let last = assign_apples_with_held(&one, &AssignmentFrame::ROBOT, [1, 0], overlap_reach)
            .expect("finite");
        assert_eq!((ids(&last.arm1), ids(&last.arm2)), (vec![], vec![7]));
        let plain = assign_apples(&one, &AssignmentFrame::ROBOT, overlap_reach).expect("finite");
        assert_eq!((ids(&plain.arm1), ids(&plain.arm2)), (vec![7], vec![]));
    }

    #[test]
    fn paper_frame_reverses_side_and_depth_axis() {
        // Arm 1 towards -y, depth along z.
        let pts = [
            Apple {
                id: AppleId(0),
                position_m: [0.0, -0.2, 0.9],
            },
            Apple {
                id: AppleId(1),
                position_m: [0.0, -0.1, 0.5],
            },
            Apple {
                id: AppleId(2),
                position_m: [0.0, 0.1, 0.7],
            },
            Apple {
                id: AppleId(3),
                position_m: [0.0, 0.2, 0.6],
            },
        ];
        let a =
            assign_apples(&pts, &AssignmentFrame::PAPER_ALGORITHM_1, |_, _| true).expect("finite");
        assert_eq!(ids(&a.arm1), vec![1, 0]);
        assert_eq!(ids(&a.arm2), vec![3, 2]);
    }

    #[test]
    fn non_finite_position_is_refused_by_name() {
        let pts = [apple(9, f64::NAN, 0.0)];
        let err = assign_apples(&pts, &AssignmentFrame::ROBOT, |_, _| true).expect_err("NaN");
        assert_eq!(
            std::mem::discriminant(&err),
            std::mem::discriminant(&AssignError::NonFinitePosition {
                id: AppleId(9),
                position_m: [0.0; 3]
            })
        );
        assert!(err.to_string().contains("AppleId(9)"));
    }

    /// Random scenes: a partition of the input, reachability respected, queues depth-sorted,
    /// balanced when the shared region allows it, and no shared apple of arm 2 lies on arm 1's
    /// side of a shared apple of arm 1 (the lateral split).
    #[test]
    fn random_scenes_satisfy_the_algorithm_invariants() {
        let mut rng = SmallRng::seed_from_u64(3);
        let frame = AssignmentFrame::ROBOT;
        for _ in 0..2000 {
            let n = rng.random_range(0..25u32);
            let apples: Vec<Apple> = (0..n)
                .map(|i| apple(i, rng.random_range(0.2..1.2), rng.random_range(-0.4..0.4)))
                .collect();
            let a = assign_apples(&apples, &frame, overlap_reach).expect("finite");
            let mut all: Vec<u32> = ids(&a.arm1);
            all.extend(ids(&a.arm2));
            all.extend(ids(&a.unreachable));
            all.sort_unstable();
            assert_eq!(all, (0..n).collect::<Vec<_>>());
            for (arm, q) in [(ArmId::Arm1, &a.arm1), (ArmId::Arm2, &a.arm2)] {
                assert!(q.iter().all(|p| overlap_reach(arm, &p.position_m)));
                assert!(
                    q.windows(2)
                        .all(|w| w[0].position_m[0] <= w[1].position_m[0])
                );
            }
            assert!(a.unreachable.iter().all(|p| {
                !overlap_reach(ArmId::Arm1, &p.position_m)
                    && !overlap_reach(ArmId::Arm2, &p.position_m)
            }));
            let reach = a.arm1.len() + a.arm2.len();
            let shared = |p: &&Apple| {
                overlap_reach(ArmId::Arm1, &p.position_m)
                    && overlap_reach(ArmId::Arm2, &p.position_m)
            };
            let shared1: Vec<&Apple> = a.arm1.iter().filter(shared).collect();
            let shared2: Vec<&Apple> = a.arm2.iter().filter(shared).collect();
            // Arm 1 took shared apples only while it was below half.
            if !shared1.is_empty() {
                assert!(2 * a.arm1.len() <= reach + 1);
            }
            if !shared2.is_empty() {
                assert!(2 * a.arm1.len() >= reach);
            }
            let min1 = shared1
                .iter()
                .map(|p| p.position_m[1])
                .fold(f64::INFINITY, f64::min);
            let max2 = shared2
                .iter()
                .map(|p| p.position_m[1])
                .fold(f64::NEG_INFINITY, f64::max);
            assert!(shared1.is_empty() || shared2.is_empty() || min1 >= max2);
        }
    }
}
