//! Property test of the scenario reader (issue 18, item 3): every preset scenario with values
//! replaced by anything (NaN, negative, huge, wrongly typed), lines dropped or doubled and bytes
//! changed: the scenario is accepted (and its camera accessors work) or refused with an error
//! naming the file; never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup is a failed test

use harvest_sim::scenario::Scenario;
use proptest::prelude::*;

/// Cases per property (each parses one scenario text).
const CASES: u32 = 256;

const PRESETS: [&str; 4] = [
    include_str!("../scenarios/default.toml"),
    include_str!("../scenarios/fuji_ufo.toml"),
    include_str!("../scenarios/gala_vertical_wall.toml"),
    include_str!("../scenarios/ideal.toml"),
];

/// Values that break settings: NaN, infinities, signs, zeros, extremes, wrong types.
const WILD_VALUES: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "-0.0",
    "1e308",
    "5e-324",
    "18446744073709551615",
    "9223372036854775807",
    "-9223372036854775808",
    "\"\"",
    "\"x\"",
    "true",
    "[]",
    "[nan, inf, -1]",
    "{}",
    "0.000001",
    "100000",
];

/// One edit of a TOML text.
#[derive(Debug, Clone)]
enum TomlEdit {
    /// The value of the n-th `key = value` line replaced.
    Value(prop::sample::Index, &'static str),
    /// The n-th line removed.
    DropLine(prop::sample::Index),
    /// The n-th line written twice.
    DuplicateLine(prop::sample::Index),
    /// One byte replaced (syntax errors, cut strings, control characters).
    Byte(prop::sample::Index, u8),
}

fn toml_edit() -> impl Strategy<Value = TomlEdit> {
    prop_oneof![
        6 => (any::<prop::sample::Index>(), prop::sample::select(WILD_VALUES))
            .prop_map(|(i, v)| TomlEdit::Value(i, v)),
        1 => any::<prop::sample::Index>().prop_map(TomlEdit::DropLine),
        1 => any::<prop::sample::Index>().prop_map(TomlEdit::DuplicateLine),
        1 => (any::<prop::sample::Index>(), any::<u8>()).prop_map(|(i, b)| TomlEdit::Byte(i, b)),
    ]
}

/// `text` with `edits` applied in order.
fn mutate_toml(text: &str, edits: &[TomlEdit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for edit in edits {
        if lines.is_empty() {
            break;
        }
        match edit {
            TomlEdit::Value(index, value) => {
                let assignments: Vec<usize> = (0..lines.len())
                    .filter(|&i| !lines[i].trim_start().starts_with('#') && lines[i].contains('='))
                    .collect();
                if assignments.is_empty() {
                    continue;
                }
                let line = &mut lines[assignments[index.index(assignments.len())]];
                if let Some(at) = line.find('=') {
                    line.truncate(at + 1);
                    line.push(' ');
                    line.push_str(value);
                }
            }
            TomlEdit::DropLine(index) => {
                let at = index.index(lines.len());
                lines.remove(at);
            }
            TomlEdit::DuplicateLine(index) => {
                let at = index.index(lines.len());
                let line = lines[at].clone();
                lines.insert(at, line);
            }
            TomlEdit::Byte(index, byte) => {
                let mut bytes = lines.join("\n").into_bytes();
                if bytes.is_empty() {
                    continue;
                }
                let at = index.index(bytes.len());
                bytes[at] = *byte;
                lines = String::from_utf8_lossy(&bytes)
                    .lines()
                    .map(str::to_owned)
                    .collect();
            }
        }
    }
    lines.join("\n")
}

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
