//! Ground truth of the simulated world, for evaluating perception and harvesting only: the robot
//! software must never read it.

use crate::orchard::{AppleId, AppleState, World};

/// The true state of one apple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AppleTruth {
    pub id: AppleId,
    /// Current centre, robot frame, metres.
    pub center_in_robot_m: [f64; 3],
    pub radius_m: f64,
    pub state: AppleState,
    /// Pull that detaches it, newtons (above the suction force for an unripe apple).
    pub stem_strength_n: f64,
    pub cluster: Option<u32>,
    pub heavily_occluded: bool,
    pub overexposed: bool,
}

/// The true state of every apple of the simulated world, in [`AppleId`] order, as the simulator
/// holds it in process: everything it knows about each apple (stem strength, cluster, occlusion,
/// exposure) for the in-process evaluations. Not the `sim/ground_truth` payload
/// `harvest_ipc::payloads::GroundTruth`, which carries a bounded subset of it (id, state, centre,
/// radius) to evaluation tools in other processes (`physics_thread.rs` fills it from this).
#[derive(Debug, Clone, PartialEq)]
pub struct WorldTruth {
    pub time_s: f64,
    pub apples: Vec<AppleTruth>,
}

impl WorldTruth {
    /// How many apples are in `state`.
    pub fn count(&self, state: AppleState) -> usize {
        self.apples
            .iter()
            .filter(|apple| apple.state == state)
            .count()
    }
}

impl World {
    /// True apple centres, radii and states (evaluation only).
    pub fn ground_truth(&self) -> WorldTruth {
        WorldTruth {
            time_s: self.time_s(),
            apples: self
                .apples()
                .iter()
                .map(|apple| AppleTruth {
                    id: apple.id,
                    center_in_robot_m: apple.center_in_robot_m,
                    radius_m: apple.radius_m,
                    state: apple.state,
                    stem_strength_n: apple.stem_strength_n,
                    cluster: apple.cluster,
                    heavily_occluded: apple.heavily_occluded,
                    overexposed: apple.overexposed,
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::orchard::{AppleState, World};
    use crate::scenario::Scenario;

    #[test]
    fn ground_truth_mirrors_the_world() {
        let world =
            World::generate(&Scenario::preset("default").expect("default"), 2).expect("world");
        let truth = world.ground_truth();
        assert_eq!(truth.apples.len(), world.apples().len());
        assert_eq!(truth.count(AppleState::OnTree), world.apples().len());
        for (truth, apple) in truth.apples.iter().zip(world.apples()) {
            assert_eq!(truth.id, apple.id);
            assert_eq!(truth.center_in_robot_m, apple.center_in_robot_m);
            assert_eq!(truth.radius_m, apple.radius_m);
        }
    }
}
