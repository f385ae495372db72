//! No production default comes from the simulator: a process that needs a calibration refuses to
//! start without it and names the flag (the simulated robot's launch profiles pass `sim/` files).

mod common;

use common::*;
use std::time::Duration;

#[test]
fn perception_without_its_calibration_names_the_flag() {
    let domain = unique_domain("nocal");
    let (status, _, stderr) = run_harvest(&domain, &["perception"], Duration::from_secs(30));
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains("--calibration FILE is required"),
        "{stderr}"
    );

    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "perception",
            "--calibration",
            SIM_CAMERA_CALIBRATION,
            "--depth-source",
            "lidar-fused",
        ],
        Duration::from_secs(30),
    );
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains("--lidar-extrinsic FILE is required"),
        "{stderr}"
    );
    let (status, _, stderr) = run_harvest(&domain, &["laser"], Duration::from_secs(30));
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains("--calibration FILE is required"),
        "{stderr}"
    );
    assert_eq!(leftover_files(&domain), "");
}
