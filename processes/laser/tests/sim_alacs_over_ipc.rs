//! The simulated ALACS unit end to end over the hardware channels: the simulator's
//! `AlacsDeviceServer` serves `hw/alacs/command` -> `hw/alacs/image` on its own thread with its
//! own node (as the sim process does), and the laser process's driver `SimAlacsUnit` talks to it
//! from the test thread, in a domain no other test uses.
//!
//! Checks: the driver passes the ALACS conformance checks; a full scan request of a known apple
//! (the `ideal` scenario: no leaves) comes back within a few millimetres of the true centre.

mod common;

use std::time::Duration;

use common::{Device, ideal_world, unique_domain};
use harvest_hw::alacs::{
    ALACS_FROM_TOF_CAMERA, AlacsExtrinsics, SLIDE_STROKE_M, SimAlacsUnit, alacs_camera_intrinsics,
    conformance,
};
use harvest_ipc::Context;
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, LaserScanStatus};
use harvest_laser::{LaserReach, ScanConfig, ScanService};
use harvest_sim::alacs_device::robot_from_tof_color;

/// Longest wait for one device answer: generous, a debug-build render of 1440x1080 takes a while.
const DEVICE_TIMEOUT: Duration = Duration::from_secs(30);

#[test]
fn sim_driver_conforms_over_ipc() {
    let domain = unique_domain("conf");
    let device = Device::start(&domain);
    let context = Context::new(&domain, "laser").expect("context");
    let mut unit =
        SimAlacsUnit::connect(&context, alacs_camera_intrinsics(), DEVICE_TIMEOUT).expect("driver");
    conformance::check_all(&mut unit).expect("conformance");
    // 4 moves + 1 capture (stroke check) + 1 move + 2 x (laser + capture) + laser off; the
    // refused targets never reach the device.
    assert_eq!(device.finish(), 12);
}

#[test]
fn scan_of_a_known_apple_over_ipc_lands_within_a_few_millimetres() {
    let world = ideal_world();
    let tof_from_robot = robot_from_tof_color(&world).inverse();
    // The first apple the unit can scan (the laser's own reach check: in the ALACS image and a
    // scan within the stroke) without shifting the scan to fit the stroke (a shifted scan puts
    // its last lines beside the apple).
    let reach = LaserReach::new(
        AlacsExtrinsics::paper_table1(),
        alacs_camera_intrinsics(),
        ALACS_FROM_TOF_CAMERA,
        ScanConfig::default(),
    );
    let apple = world
        .apples()
        .iter()
        .find(|apple| {
            reach
                .check(
                    tof_from_robot.apply(apple.center_in_robot_m),
                    apple.radius_m,
                )
                .is_ok_and(|in_reach| {
                    let slide_m = &in_reach.plan.slide_positions_m;
                    slide_m.first().is_some_and(|&first| first > 0.01)
                        && slide_m
                            .last()
                            .is_some_and(|&last| last < SLIDE_STROKE_M - 0.01)
                })
        })
        .expect("an apple in the ALACS's reach");
    let truth_in_tof = tof_from_robot.apply(apple.center_in_robot_m);

    let domain = unique_domain("scan");
    let device = Device::start(&domain);
    let context = Context::new(&domain, "laser").expect("context");
    let intrinsics = alacs_camera_intrinsics();
    let mut unit = SimAlacsUnit::connect(&context, intrinsics, DEVICE_TIMEOUT).expect("driver");
    let mut service = ScanService::new(
        AlacsExtrinsics::paper_table1(),
        intrinsics,
        ALACS_FROM_TOF_CAMERA,
    )
    .expect("service");
    // A ToF-like rough estimate: 15 mm too deep, a few mm off sideways.
    let request = LaserScanRequest {
        request_seq: 1,
        apple_id: apple.id.0,
        rough_position_in_camera_m: [
            truth_in_tof[0] + 0.004,
            truth_in_tof[1] - 0.003,
            truth_in_tof[2] + 0.015,
        ],
        rough_radius_m: apple.radius_m,
        ..LaserScanRequest::default()
    };
    let mut result = LaserScanResult::default();
    let scan = service
        .answer(&mut unit, &request, &mut result, &mut || {})
        .expect("scan");
    assert_eq!(result.status, LaserScanStatus::Ok);
    assert_eq!(result.candidate_count, 5, "{scan:?}");
    let error_m = (0..3)
        .map(|k| (result.position_in_camera_m[k] - truth_in_tof[k]).powi(2))
        .sum::<f64>()
        .sqrt();
    let rough_error_m = (0.004_f64.powi(2) + 0.003_f64.powi(2) + 0.015_f64.powi(2)).sqrt();
    assert!(error_m < 3e-3, "laser error {error_m} m, {result:?}");
    assert!(error_m < rough_error_m / 4.0);
    // Every capture's stamp came from the device; the result carries the selected one's.
    let stamps = &service.last_motion().capture_stamps_ns;
    assert_eq!(stamps.len(), 5);
    assert_eq!(result.header.capture_ns, stamps[scan.selected]);
    // laser on, 5 x (move + capture), laser off.
    assert_eq!(device.finish(), 12);
}
