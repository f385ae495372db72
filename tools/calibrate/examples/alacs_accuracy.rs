//! Measures the ALACS pipeline end to end, as [alacs sec. 5.2] does: calibrate (method 4) on
//! generated samples, then localise rendered apples at d = 0, 5, 10, 15, 20 cm and 0.6-1.2 m with
//! the calibrated parameters, and time method 4 over repeated runs.
//!
//! `cargo run -p harvest-laser --release --example alacs_accuracy -- [SEED]`

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

use std::time::Instant;

use harvest_calibrate::laser_samples::{SampleGeneratorConfig, generate_samples};
use harvest_eval::laser::{AccuracyConfig, evaluate_localization_accuracy};
use harvest_hw::alacs::alacs_camera_intrinsics;
use harvest_laser::calibration::{
    CalibrationMethod, CalibrationOptions, calibrate, compare_methods,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seed: u64 = match std::env::args().nth(1) {
        Some(text) => text.parse()?,
        None => 1,
    };
    let intrinsics = alacs_camera_intrinsics();
    let generated = generate_samples(&SampleGeneratorConfig::paper_like(intrinsics, seed))?;
    let options = CalibrationOptions::default();
    let clean = generated.clean_mask();
    let report = compare_methods(&generated.samples, Some(&clean), &options)?;
    print!("{report}");

    const RUNS: usize = 200;
    let started = Instant::now();
    for _ in 0..RUNS {
        calibrate(
            &generated.samples,
            CalibrationMethod::HighFidelityRansac,
            &options,
        )?;
    }
    println!(
        "method 4 over {RUNS} runs: {:.3} ms per calibration ({} hypotheses)\n",
        started.elapsed().as_secs_f64() * 1e3 / RUNS as f64,
        options.ransac.iterations
    );

    let calibrated = calibrate(
        &generated.samples,
        CalibrationMethod::HighFidelityRansac,
        &options,
    )?
    .extrinsics;
    let config = AccuracyConfig {
        seed,
        ..AccuracyConfig::default()
    };
    let started = Instant::now();
    let accuracy =
        evaluate_localization_accuracy(intrinsics, &generated.truth, &calibrated, &config)?;
    print!("{accuracy}");
    println!(
        "({} images rendered and processed in {:.1} s)",
        accuracy.per_slide.iter().map(|s| s.images).sum::<usize>(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
