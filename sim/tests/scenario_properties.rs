//! Property test of the scenario reader: every preset scenario with values
//! replaced by anything (NaN, negative, huge, wrongly typed), lines dropped or doubled and bytes
//! changed: the scenario is accepted (and its camera accessors work) or refused with an error
//! naming the file; never a panic.

use harvest_sim::scenario::Scenario;
use harvest_test_support::toml_mutation::{mutate_toml, toml_edit};
use proptest::prelude::*;

/// Cases per property (each parses one scenario text).
const CASES: u32 = 256;

const PRESETS: [&str; 4] = [
    include_str!("../scenarios/default.toml"),
    include_str!("../scenarios/fuji_ufo.toml"),
    include_str!("../scenarios/gala_vertical_wall.toml"),
    include_str!("../scenarios/ideal.toml"),
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn a_mutated_scenario_is_accepted_or_refused_by_name(
        preset in 0usize..PRESETS.len(),
        edits in prop::collection::vec(toml_edit(), 1..6),
    ) {
        let text = mutate_toml(PRESETS[preset], &edits);
        match Scenario::from_toml_str("mutated.toml", &text) {
            Ok(scenario) => {
                let _ = scenario.camera.robot_from_camera();
                let _ = scenario.camera.depth_intrinsics();
                let _ = scenario.camera.color_intrinsics();
                let _ = scenario.camera.color_from_depth();
                let _ = scenario.camera.depth_sigma_mm(1000.0);
            }
            Err(error) => prop_assert!(error.to_string().contains("mutated.toml"), "{error}"),
        }
    }
}
