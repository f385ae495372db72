//! Property test of the launch-file reader: the default launch file with
//! values replaced by anything (NaN, negative, huge, wrongly typed), lines dropped or doubled
//! and bytes changed, and text of any characters: `harvest up` accepts it or refuses it with
//! an error naming the file; never a panic.

use harvest_supervisor::launch::{DEFAULT_LAUNCH, Launch};
use harvest_test_support::toml_mutation::{mutate_toml, toml_edit};
use proptest::prelude::*;
use std::path::Path;

/// Cases per property (each parses one small TOML text).
const CASES: u32 = 256;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn a_mutated_launch_file_is_accepted_or_refused_by_name(
        edits in prop::collection::vec(toml_edit(), 1..6),
    ) {
        let text = mutate_toml(DEFAULT_LAUNCH, &edits);
        match Launch::parse_in(&text, "mutated.toml", Path::new("/launch")) {
            Ok(launch) => {
                for process in &launch.processes {
                    prop_assert!(process.backoff_initial <= process.backoff_max);
                    prop_assert!(!process.name.is_empty());
                }
            }
            Err(error) => prop_assert!(error.to_string().contains("mutated.toml"), "{error}"),
        }
    }

    #[test]
    fn launch_text_of_any_characters_never_panics(text in "\\PC{0,400}") {
        if let Err(error) = Launch::parse_in(&text, "any.toml", Path::new("/launch")) {
            prop_assert!(error.to_string().contains("any.toml"), "{error}");
        }
    }
}
