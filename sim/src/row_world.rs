//! The world of a whole row: each section generated from its preset and seed, placed at its
//! position along the row, merged into one [`World`] with apple ids numbered along the row.

use crate::orchard::{AppleId, OrchardError, World};
use crate::row::RowScenario;

impl World {
    /// Generates the row's world from `seed` (each section from [`RowScenario::section_seed`],
    /// set back and lifted by [`RowScenario::section_placement_m`]), in the row frame (robot
    /// offset zero). The shared settings (camera, background,
    /// lighting, vacuum, failure rates) are the first section's; the canopy spans the row.
    pub fn generate_row(row: &RowScenario, seed: u64) -> Result<Self, OrchardError> {
        let mut merged: Option<World> = None;
        let mut clusters = 0u32;
        for (index, (section, scenario)) in row.file.sections.iter().zip(&row.scenarios).enumerate()
        {
            let mut part = World::generate(scenario, row.section_seed(index, seed))?;
            // Moving the robot by -d moves the section by +d: set back and lifted.
            let [setback_m, lift_m] = row.section_placement_m(index, seed);
            part.set_robot_offset_m([-setback_m, -section.center_m, -lift_m]);
            let world = merged.get_or_insert_with(|| {
                let mut first = part.clone();
                first.apples.clear();
                first.leaves.clear();
                first.branches.clear();
                first.robot_offset_m = [0.0; 3];
                first.scenario = scenario.clone();
                first.scenario.name = row.file.name.clone();
                first.scenario.canopy.y_range_m = row.extent_m();
                first
            });
            let mut section_clusters = 0u32;
            for mut apple in part.apples {
                apple.id = AppleId(world.apples.len() as u32);
                if let Some(cluster) = apple.cluster {
                    section_clusters = section_clusters.max(cluster + 1);
                    apple.cluster = Some(clusters + cluster);
                }
                world.apples.push(apple);
            }
            clusters += section_clusters;
            world.leaves.extend(part.leaves);
            world.branches.extend(part.branches);
        }
        let Some(world) = merged else {
            // RowScenario guarantees a section; an empty row is an empty world of no scenario.
            return Err(OrchardError::EmptyRow);
        };
        tracing::debug!(
            row = %row.file.name,
            seed,
            sections = row.file.sections.len(),
            apples = world.apples.len(),
            "generated row world"
        );
        Ok(world)
    }
}

#[cfg(test)]
mod tests {
    use crate::orchard::World;
    use crate::row::RowScenario;

    const ROW: &str = r#"name = "two"
[[section]]
canopy = "default"
center_m = 0.0
[[section]]
canopy = "fuji_ufo"
center_m = 2.0
seed = 5
"#;

    #[test]
    fn sections_are_placed_along_the_row_and_numbered() {
        let row = RowScenario::from_toml_str("row.toml", ROW).expect("row");
        let world = World::generate_row(&row, 1).expect("world");
        let first = World::generate(&row.scenarios[0], 1).expect("section 1");
        let second = World::generate(&row.scenarios[1], 5).expect("section 2");
        assert_eq!(
            world.apples().len(),
            first.apples().len() + second.apples().len()
        );
        for (index, apple) in world.apples().iter().enumerate() {
            assert_eq!(apple.id.0 as usize, index);
        }
        let shifted = &world.apples()[first.apples().len()];
        let original = &second.apples()[0];
        assert!(
            (shifted.center_in_robot_m[1] - (original.center_in_robot_m[1] + 2.0)).abs() < 1e-12
        );
        assert_eq!(
            World::generate_row(&row, 1).expect("again").apples(),
            world.apples()
        );
    }
}
