//! Property tests of the laser calibration readers (issue 18, item 3): sample CSVs of any
//! numbers (and with fields replaced by anything), through the reader and all four calibration
//! methods, and the calibration file with values replaced by anything, lines dropped or doubled
//! and bytes changed. Every failure is an error naming the file (and the line); a calibration
//! that succeeds has finite extrinsics; never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup is a failed test

use harvest_laser::calibration::{
    CalibrationMethod, CalibrationOptions, CalibrationSample, calibrate, parse_samples_csv,
    read_calibration_file,
};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

/// Cases per property (the CSV one runs four fits on up to 40 samples).
const CASES: u32 = 64;

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

/// Field values that break a sample CSV.
const WILD_FIELDS: &[&str] = &[
    "nan", "inf", "-inf", "1e309", "-0", "5e-324", "", "-", "0x10", " ", "1.0.0", "1e308",
];

fn sample_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1.0f64..1.0,
        4 => 0.2f64..2.0,
        1 => prop::sample::select(vec![0.0, -0.0, 1e308, -1e308, 5e-324, 1e-300]),
        1 => any::<f64>().prop_filter("finite", |v| v.is_finite()),
    ]
}

/// Mostly plausible samples (normalized image coordinates, 0.4-1.5 m deep: the fits run), some
/// of any finite numbers.
fn sample() -> impl Strategy<Value = CalibrationSample> {
    prop_oneof![
        8 => (-0.5f64..0.5, -0.4f64..0.4, 0.4f64..1.5),
        1 => (sample_value(), sample_value(), sample_value()),
    ]
    .prop_map(|(u_bar, v_bar, z_m)| CalibrationSample { u_bar, v_bar, z_m })
}

fn csv_text(samples: &[CalibrationSample]) -> String {
    let mut text = String::from("u_bar,v_bar,z_m\n");
    for s in samples {
        text.push_str(&format!("{:?},{:?},{:?}\n", s.u_bar, s.v_bar, s.z_m));
    }
    text
}

fn scratch_file(text: &str) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!(
        "harvest-laser-calibration-prop-{}-{}.toml",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&path, text).expect("write");
    path
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Sample files of any finite numbers, some fields replaced by anything.
    #[test]
    fn sample_files_are_read_and_fitted_or_refused_by_name(
        samples in prop::collection::vec(sample(), 0..60),
        edits in prop::collection::vec(
            (any::<prop::sample::Index>(), 0usize..3, prop::sample::select(WILD_FIELDS)),
            0..3,
        ),
    ) {
        let text = csv_text(&samples);
        let mut lines: Vec<Vec<String>> = text
            .lines()
            .map(|line| line.split(',').map(str::to_owned).collect())
            .collect();
        for (line, column, value) in &edits {
            let line = line.index(lines.len());
            lines[line][*column] = (*value).to_owned();
        }
        let text: Vec<String> = lines.iter().map(|fields| fields.join(",")).collect();
        let path = Path::new("/data/samples.csv");
        let parsed = match parse_samples_csv(&text.join("\n"), path) {
            Ok(parsed) => parsed,
            Err(error) => {
                prop_assert!(error.to_string().contains("/data/samples.csv"), "{error}");
                return Ok(());
            }
        };
        for method in CalibrationMethod::ALL {
            match calibrate(&parsed, method, &CalibrationOptions::default()) {
                Ok(calibration) => {
                    let e = calibration.extrinsics;
                    prop_assert!(
                        e.alpha_rad.is_finite() && e.l0_m.is_finite() && e.beta_rad.is_finite(),
                        "{method:?}: {e:?}"
                    );
                }
                Err(error) => prop_assert!(!error.to_string().is_empty()),
            }
        }
    }

    /// Sample text of any characters.
    #[test]
    fn sample_text_of_any_characters_never_panics(text in "\\PC{0,300}") {
        if let Err(error) = parse_samples_csv(&text, Path::new("/data/any.csv")) {
            prop_assert!(error.to_string().contains("/data/any.csv"), "{error}");
        }
    }

    /// The simulated unit's calibration file, mutated.
    #[test]
    fn a_mutated_calibration_file_is_read_or_refused_by_name(
        edits in prop::collection::vec(toml_edit(), 1..5),
    ) {
        let text = mutate_toml(include_str!("../../../sim/alacs_calibration.toml"), &edits);
        let path = scratch_file(&text);
        let read = read_calibration_file(&path);
        let _ = std::fs::remove_file(&path);
        match read {
            Ok(file) => prop_assert!(file.alacs_extrinsics().is_some()),
            Err(error) => prop_assert!(
                error.to_string().contains("harvest-laser-calibration-prop"),
                "{error}"
            ),
        }
    }
}
