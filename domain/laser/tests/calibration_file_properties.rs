//! Property tests of the laser calibration readers: sample CSVs of any
//! numbers (and with fields replaced by anything), through the reader and all four calibration
//! methods, and the calibration file with values replaced by anything, lines dropped or doubled
//! and bytes changed. Every failure is an error naming the file (and the line); a calibration
//! that succeeds has finite extrinsics; never a panic.

use harvest_laser::calibration::{
    CalibrationMethod, CalibrationOptions, CalibrationSample, calibrate, parse_samples_csv,
    read_calibration_file,
};
use harvest_test_support::toml_mutation::{mutate_toml, scratch_file, toml_edit};
use proptest::prelude::*;
use std::path::Path;

/// Cases per property (the CSV one runs four fits on up to 40 samples).
const CASES: u32 = 64;

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
        let path = scratch_file("harvest-laser-calibration-prop", &text);
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
