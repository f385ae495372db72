//! The `laser` process loop (`process::run_until`) on a thread with its own node, the
//! simulator's ALACS device on another, and the test acting as perception: it waits for the
//! process's heartbeat, sends scan requests on `laser/scan_request` and reads the answers on
//! `laser/scan_result`.
//!
//! Checks: a known apple's request is answered with status 0 within a few millimetres of the
//! truth (ToF colour-camera frame, as requested) and echoes the request's ids; an apple out of
//! the slide's reach gets status 2 without moving the device; the loop stops cleanly.

mod common;

use common::{Device, Laser, ideal_world, unique_domain, wait_for};
use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsExtrinsics, alacs_camera_intrinsics};
use harvest_ipc::Context;
use harvest_ipc::catalogue::{LASER_SCAN_REQUEST, LASER_SCAN_RESULT, PROCESS_HEALTH};
use harvest_ipc::payloads::{LaserScanRequest, LaserScanResult, LaserScanStatus};
use harvest_laser::{LaserReach, ScanConfig};
use harvest_sim::alacs_device::robot_from_tof_color;

#[test]
fn laser_process_answers_scan_requests() {
    let world = ideal_world();
    let tof_from_robot = robot_from_tof_color(&world).inverse();
    // The laser's own reach check (in the ALACS image and a scan within the stroke), the one
    // the process applies before it scans.
    let reach = LaserReach::new(
        AlacsExtrinsics::paper_table1(),
        alacs_camera_intrinsics(),
        ALACS_FROM_TOF_CAMERA,
        ScanConfig::default(),
    );
    // A ToF-like rough estimate of an apple: a few mm off sideways, 12 mm too deep.
    let rough = |apple: &harvest_sim::Apple| {
        let truth_in_tof = tof_from_robot.apply(apple.center_in_robot_m);
        [
            truth_in_tof[0] - 0.003,
            truth_in_tof[1] + 0.002,
            truth_in_tof[2] + 0.012,
        ]
    };
    let in_reach = |apple: &harvest_sim::Apple| {
        let truth_in_tof = tof_from_robot.apply(apple.center_in_robot_m);
        reach.check(truth_in_tof, apple.radius_m).is_ok()
            && reach.check(rough(apple), apple.radius_m + 0.003).is_ok()
    };
    let reachable = world
        .apples()
        .iter()
        .find(|apple| in_reach(apple))
        .expect("an apple in reach");
    let unreachable = world
        .apples()
        .iter()
        .find(|apple| reach.check(rough(apple), apple.radius_m + 0.003).is_err())
        .expect("an apple out of reach");

    let domain = unique_domain("proc");
    let device = Device::start(&domain);
    let laser = Laser::start(&domain);

    let context = Context::new(&domain, "perception_test").expect("context");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let mut requests = context.publisher(LASER_SCAN_REQUEST).expect("requests");
    let results = context.subscriber(LASER_SCAN_RESULT).expect("results");
    // The first heartbeat comes from the running loop: the request subscriber exists by then.
    wait_for(&health, |beat| beat.process_name.as_str() == "laser");

    for (request_seq, apple) in [(1, reachable), (2, unreachable)] {
        let truth_in_tof = tof_from_robot.apply(apple.center_in_robot_m);
        let request = LaserScanRequest {
            request_seq,
            apple_id: apple.id.0,
            rough_position_in_camera_m: rough(apple),
            rough_radius_m: apple.radius_m + 0.003,
            ..LaserScanRequest::default()
        };
        requests.publish(&request).expect("publish request");
        let result: LaserScanResult = wait_for(&results, |r| r.request_seq == request_seq);
        assert_eq!(result.apple_id, apple.id.0);
        if request_seq == 1 {
            assert_eq!(result.status, LaserScanStatus::Ok, "{result:?}");
            let error_m = (0..3)
                .map(|k| (result.position_in_camera_m[k] - truth_in_tof[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(error_m < 3e-3, "error {error_m} m: {result:?}");
            assert!(result.candidate_count >= 3, "{result:?}");
            assert!(result.scan_duration_ns > 0);
        } else {
            assert_eq!(result.status, LaserScanStatus::OutOfReach, "{result:?}");
            assert_eq!(result.candidate_count, 0);
            assert_eq!(
                result.position_in_camera_m,
                request.rough_position_in_camera_m
            );
        }
    }

    laser.finish();
    // One scan: laser on, 5 x (move + capture), laser off; the unreachable apple never reached
    // the device.
    assert_eq!(device.finish(), 12);
}
