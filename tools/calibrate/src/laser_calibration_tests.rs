//! Algorithm 1 and the Table 1 methods recover the parameters the sample generator used.

use crate::laser_samples::*;
use harvest_hw::alacs::alacs_camera_intrinsics;
use harvest_laser::calibration::*;

fn paper_like(seed: u64) -> GeneratedSamples {
    generate_samples(&SampleGeneratorConfig::paper_like(
        alacs_camera_intrinsics(),
        seed,
    ))
    .expect("generate")
}

#[test]
fn method_4_recovers_the_generating_parameters() {
    for seed in 1..=5 {
        let generated = paper_like(seed);
        let calibration = calibrate(
            &generated.samples,
            CalibrationMethod::HighFidelityRansac,
            &CalibrationOptions::default(),
        )
        .expect("calibrate");
        let (fit, truth) = (calibration.extrinsics, generated.truth);
        assert!(
            (fit.alpha_rad - truth.alpha_rad).abs().to_degrees() < 0.1,
            "seed {seed}: alpha {} deg",
            fit.alpha_rad.to_degrees()
        );
        assert!(
            (fit.l0_m - truth.l0_m).abs() < 2e-3,
            "seed {seed}: L0 {} m",
            fit.l0_m
        );
        assert!(
            (fit.beta_rad - truth.beta_rad).abs().to_degrees() < 0.1,
            "seed {seed}: beta {} deg",
            fit.beta_rad.to_degrees()
        );
        // Every planted outlier is left out of the final fit.
        for (index, outlier) in generated.is_outlier.iter().enumerate() {
            if *outlier {
                assert!(
                    !calibration.used.contains(&index),
                    "seed {seed}: outlier {index} used"
                );
            }
        }
    }
}

#[test]
fn comparison_ranks_like_table_1() {
    let generated = paper_like(1);
    let clean = generated.clean_mask();
    let report = compare_methods(
        &generated.samples,
        Some(&clean),
        &CalibrationOptions::default(),
    )
    .expect("compare");
    let error = |method| report.method(method).expect("row").mean_abs_error_mm;
    // RANSAC with the high-fidelity model is best, and beats the all-data fit.
    assert!(
        error(CalibrationMethod::HighFidelityRansac)
            < error(CalibrationMethod::HighFidelityAllData)
    );
    assert!(
        error(CalibrationMethod::HighFidelityAllData)
            < error(CalibrationMethod::LowFidelityAllData)
    );
    assert!(
        error(CalibrationMethod::HighFidelityRansac) < error(CalibrationMethod::LowFidelityRansac)
    );
    assert!(
        report
            .method(CalibrationMethod::LowFidelityAllData)
            .expect("row")
            .beta_deg
            .is_none()
    );
    assert_eq!(report.evaluation_samples, 27);
    let table = report.to_string();
    assert!(table.contains("4 high-fidelity + RANSAC"), "{table}");
}

#[test]
fn method_2_removes_outliers_not_the_clean_samples_its_model_misfits() {
    for seed in 1..=5 {
        let generated = paper_like(seed);
        let options = CalibrationOptions::default();
        let method_2 = calibrate(
            &generated.samples,
            CalibrationMethod::LowFidelityRansac,
            &options,
        )
        .expect("method 2");
        let clean_used = method_2
            .used
            .iter()
            .filter(|&&index| !generated.is_outlier[index])
            .count();
        // 27 clean samples; the low-fidelity model's structural error is several mm, so
        // its threshold must be wider than the 2 mm floor to keep them.
        assert!(
            clean_used >= 24,
            "seed {seed}: {clean_used} clean samples kept"
        );
        let threshold_m = method_2.threshold_m.expect("RANSAC threshold");
        assert!(threshold_m > options.ransac.epsilon_m, "seed {seed}");
        // The high-fidelity model fits clean data to well under 2 mm: its threshold stays
        // epsilon, so Algorithm 1 runs as written.
        let method_4 = calibrate(
            &generated.samples,
            CalibrationMethod::HighFidelityRansac,
            &options,
        )
        .expect("method 4");
        assert_eq!(method_4.threshold_m, Some(options.ransac.epsilon_m));
    }
}

#[test]
fn lmeds_scale_of_gaussian_residuals() {
    // The median of |N(0, sigma)| is 0.6745 sigma; the small-sample factor is 1 + 5/(n-p).
    let sigma = fit::lmeds_sigma_m(0.6745, 1_000_005, 5);
    assert!((sigma - 1.0).abs() < 1e-3, "{sigma}");
    assert!((fit::lmeds_sigma_m(1.0, 30, 2) - 1.4826 * (1.0 + 5.0 / 28.0)).abs() < 1e-12);
}

#[test]
fn bad_sample_sets_are_refused() {
    let options = CalibrationOptions::default();
    let generated = paper_like(2);
    let samples = &generated.samples;
    for method in CalibrationMethod::ALL {
        assert_eq!(
            calibrate(&samples[..3], method, &options),
            Err(CalibrationError::TooFewSamples { got: 3, needed: 4 })
        );
    }
    let mut with_nan = samples.clone();
    with_nan[5].v_bar = f64::NAN;
    assert!(matches!(
        calibrate(&with_nan, CalibrationMethod::HighFidelityRansac, &options),
        Err(CalibrationError::NonFiniteSample {
            index: 5,
            field: "v_bar",
            ..
        })
    ));
    let one_depth: Vec<CalibrationSample> = samples
        .iter()
        .map(|s| CalibrationSample { z_m: 0.8, ..*s })
        .collect();
    assert!(matches!(
        calibrate(&one_depth, CalibrationMethod::HighFidelityAllData, &options),
        Err(CalibrationError::SingleDepth { .. })
    ));
    // Samples on one image line at different depths: the model is not determined.
    let collinear: Vec<CalibrationSample> = (0..8)
        .map(|k| CalibrationSample {
            u_bar: -0.1,
            v_bar: 0.05 * k as f64 - 0.2,
            z_m: 0.7 + 0.05 * k as f64,
        })
        .collect();
    assert!(matches!(
        calibrate(&collinear, CalibrationMethod::HighFidelityAllData, &options),
        Err(CalibrationError::Degenerate { .. })
    ));
    assert!(matches!(
        calibrate(&collinear, CalibrationMethod::HighFidelityRansac, &options),
        Err(CalibrationError::NoConsensus { .. })
    ));
    let no_iterations = CalibrationOptions {
        ransac: RansacOptions {
            iterations: 0,
            ..options.ransac
        },
        ..options
    };
    assert!(matches!(
        calibrate(
            samples,
            CalibrationMethod::LowFidelityRansac,
            &no_iterations
        ),
        Err(CalibrationError::InvalidOption {
            name: "iterations",
            ..
        })
    ));
}
