//! Any bytes as a calibration input (the first byte picks which): the laser sample CSV (then
//! all four calibration methods), a LiDAR cloud CSV, a data-set PNG. Every failure must name the
//! file; a successful calibration is finite.
#![no_main]

use harvest_calibrate::lidar::calibration_data::{parse_cloud_csv, read_png_grey};
use harvest_laser::calibration::{
    CalibrationMethod, CalibrationOptions, calibrate, parse_samples_csv,
};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    match pick % 3 {
        0 => {
            let Ok(text) = std::str::from_utf8(bytes) else {
                return;
            };
            match parse_samples_csv(text, Path::new("fuzzed.csv")) {
                Ok(samples) => {
                    for method in CalibrationMethod::ALL {
                        if let Ok(calibration) =
                            calibrate(&samples, method, &CalibrationOptions::default())
                        {
                            let e = calibration.extrinsics;
                            assert!(e.alpha_rad.is_finite() && e.l0_m.is_finite());
                        }
                    }
                }
                Err(error) => assert!(error.to_string().contains("fuzzed.csv")),
            }
        }
        1 => {
            let Ok(text) = std::str::from_utf8(bytes) else {
                return;
            };
            if let Err(error) = parse_cloud_csv(text, Path::new("fuzzed.csv")) {
                assert!(error.to_string().contains("fuzzed.csv"));
            }
        }
        _ => {
            let path = std::env::temp_dir()
                .join(format!("harvest-fuzz-png-{}.png", std::process::id()));
            std::fs::write(&path, bytes).expect("write");
            if let Err(error) = read_png_grey(&path) {
                assert!(error.to_string().contains("harvest-fuzz-png"));
            }
        }
    }
});
