//! The robot moving through the world: the trailer along the row, the platform's stages in-out
//! and up-down.
//!
//! The world's geometry (apples, leaves, branches, the backdrop's planes) is kept in the robot
//! frame, which is what the renderers, the physics and the arms' reach all use. When the robot
//! moves by `d` in the row frame, everything fixed to the world moves by `-d` in the robot
//! frame: apples on the tree or on the ground, leaves, branches, the ground and the next row.
//! What rides on the robot does not move: apples held by a cup or released onto the dropping
//! module. The row frame is the robot frame at offset zero (see [`crate::row`]).

use crate::orchard::{AppleState, World};

impl World {
    /// Where the robot stands in the row frame `[x in-out, y along the row, z up]`, m.
    pub fn robot_offset_m(&self) -> [f64; 3] {
        self.robot_offset_m
    }

    /// Moves the robot to `offset_m` in the row frame (non-finite offsets are ignored).
    pub fn set_robot_offset_m(&mut self, offset_m: [f64; 3]) {
        if offset_m.iter().any(|value| !value.is_finite()) || offset_m == self.robot_offset_m {
            return;
        }
        let d: [f64; 3] = std::array::from_fn(|i| offset_m[i] - self.robot_offset_m[i]);
        let shift = |p: &mut [f64; 3]| {
            for i in 0..3 {
                p[i] -= d[i];
            }
        };
        for apple in &mut self.apples {
            shift(&mut apple.rest_center_in_robot_m);
            if matches!(apple.state, AppleState::OnTree | AppleState::Dropped) {
                shift(&mut apple.center_in_robot_m);
            }
        }
        for leaf in &mut self.leaves {
            shift(&mut leaf.center_in_robot_m);
        }
        for branch in &mut self.branches {
            shift(&mut branch.start_in_robot_m);
            shift(&mut branch.end_in_robot_m);
        }
        let scenario = &mut self.scenario;
        scenario.canopy.front_x_m -= d[0];
        scenario.canopy.y_range_m = scenario.canopy.y_range_m.map(|y| y - d[1]);
        scenario.canopy.z_range_m = scenario.canopy.z_range_m.map(|z| z - d[2]);
        scenario.background.next_row_x_m -= d[0];
        scenario.background.ground_z_m -= d[2];
        scenario.background.next_row_top_z_m -= d[2];
        self.robot_offset_m = offset_m;
    }
}

#[cfg(test)]
mod tests {
    use crate::orchard::{AppleState, World};
    use crate::scenario::Scenario;
    use harvest_ipc::ArmId;

    #[test]
    fn the_world_moves_opposite_to_the_robot_and_back() {
        let mut world =
            World::generate(&Scenario::preset("default").expect("preset"), 3).expect("world");
        let original = world.clone();
        world.apples[1].state = AppleState::Harvested;
        world.apples[2].state = AppleState::Attached {
            arm: ArmId::Arm1,
            detached: true,
        };
        world.set_robot_offset_m([0.2, 1.0, 0.3]);
        let a = &world.apples()[0];
        let o = &original.apples()[0];
        assert!((a.center_in_robot_m[0] - (o.center_in_robot_m[0] - 0.2)).abs() < 1e-12);
        assert!((a.center_in_robot_m[1] - (o.center_in_robot_m[1] - 1.0)).abs() < 1e-12);
        assert!((a.center_in_robot_m[2] - (o.center_in_robot_m[2] - 0.3)).abs() < 1e-12);
        // Carried by the robot: unchanged.
        assert_eq!(world.apples()[1].center_in_robot_m, o_center(&original, 1));
        assert_eq!(world.apples()[2].center_in_robot_m, o_center(&original, 2));
        assert!(
            (world.scenario().background.ground_z_m
                - (original.scenario().background.ground_z_m - 0.3))
                .abs()
                < 1e-12
        );
        world.set_robot_offset_m([0.0; 3]);
        for (moved, start) in world.leaves().iter().zip(original.leaves()) {
            for i in 0..3 {
                assert!((moved.center_in_robot_m[i] - start.center_in_robot_m[i]).abs() < 1e-12);
            }
        }
        world.set_robot_offset_m([f64::NAN, 0.0, 0.0]);
        assert_eq!(world.robot_offset_m(), [0.0; 3]);
    }

    fn o_center(world: &World, index: usize) -> [f64; 3] {
        world.apples()[index].center_in_robot_m
    }
}
