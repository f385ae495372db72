//! The `laser` process loop (`process::run_until`) on a thread against a slow simulated ALACS
//! device (every answer [`DEVICE_DELAY`] late, so that one scan of 12 exchanges takes longer
//! than the supervisor's 3 s hang timeout), with the test acting as perception and as the
//! executive.
//!
//! Checks: the heartbeat keeps going out while a scan runs (no gap near the hang timeout; it
//! names the apple being scanned); an emergency stop engaged mid-scan ends the scan at once
//! with the laser off and its request answered with status `DeviceError`, and the scan is not
//! resumed when the stop is released.

mod common;

use std::time::Duration;

use common::{Device, Laser, WATCHDOG, ideal_world, unique_domain, wait_for};
use harvest_hw::alacs::{ALACS_FROM_TOF_CAMERA, AlacsExtrinsics, alacs_camera_intrinsics};
use harvest_ipc::catalogue::{
    EMERGENCY_STOP, LASER_SCAN_REQUEST, LASER_SCAN_RESULT, PROCESS_HEALTH,
};
use harvest_ipc::payloads::{
    EmergencyStop, LaserScanRequest, LaserScanResult, LaserScanStatus, ProcessHealth,
};
use harvest_ipc::{Context, Flow, MonotonicClock, Waiter};
use harvest_laser::{LaserReach, ScanConfig};
use harvest_sim::alacs_device::robot_from_tof_color;

/// How late the device answers each exchange.
const DEVICE_DELAY: Duration = Duration::from_millis(400);

/// The supervisor's hang timeout (`harvest up`'s default).
const HANG_TIMEOUT_NS: u64 = 3_000_000_000;

/// A request for the first apple of the ideal world in the laser's reach, 12 mm too deep.
fn request_in_reach(request_seq: u32) -> LaserScanRequest {
    let world = ideal_world();
    let tof_from_robot = robot_from_tof_color(&world).inverse();
    let reach = LaserReach::new(
        AlacsExtrinsics::paper_table1(),
        alacs_camera_intrinsics(),
        ALACS_FROM_TOF_CAMERA,
        ScanConfig::default(),
    );
    let (apple, truth_in_tof) = world
        .apples()
        .iter()
        .map(|apple| (apple, tof_from_robot.apply(apple.center_in_robot_m)))
        .find(|(apple, truth_in_tof)| {
            let rough = [truth_in_tof[0], truth_in_tof[1], truth_in_tof[2] + 0.012];
            reach.check(*truth_in_tof, apple.radius_m).is_ok()
                && reach.check(rough, apple.radius_m).is_ok()
        })
        .expect("an apple in reach");
    LaserScanRequest {
        request_seq,
        apple_id: apple.id.0,
        rough_position_in_camera_m: [truth_in_tof[0], truth_in_tof[1], truth_in_tof[2] + 0.012],
        rough_radius_m: apple.radius_m,
        ..LaserScanRequest::default()
    }
}

fn is_laser(beat: &ProcessHealth) -> bool {
    beat.process_name.as_str() == "laser"
}

#[test]
fn heartbeats_keep_flowing_during_a_long_scan() {
    let domain = unique_domain("slowbeat");
    let device = Device::start_slow(&domain, DEVICE_DELAY);
    let laser = Laser::start(&domain);
    let context = Context::new(&domain, "perception_test").expect("context");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let mut requests = context.publisher(LASER_SCAN_REQUEST).expect("requests");
    let results = context.subscriber(LASER_SCAN_RESULT).expect("results");
    wait_for(&health, is_laser);

    let request = request_in_reach(1);
    let sent_ns = MonotonicClock::read_ns();
    requests.publish(&request).expect("publish request");
    // Every laser heartbeat until the answer, event-driven on both channels.
    let mut beats: Vec<ProcessHealth> = Vec::new();
    let mut answer: Option<LaserScanResult> = None;
    let waiter = Waiter::new().expect("waiter");
    let health_guard = waiter
        .attach_listener(health.listener())
        .expect("attach health");
    let results_guard = waiter
        .attach_listener(results.listener())
        .expect("attach results");
    let watchdog = waiter.attach_interval(WATCHDOG).expect("watchdog");
    waiter
        .run(|attachment| -> Result<Flow, String> {
            if attachment.has_event_from(&health_guard) {
                while let Some(beat) = health.receive().expect("receive") {
                    if is_laser(&beat) {
                        beats.push(*beat);
                    }
                }
            }
            if attachment.has_event_from(&results_guard) {
                while let Some(result) = results.receive().expect("receive") {
                    answer = Some(*result);
                }
            }
            if answer.is_some() {
                return Ok(Flow::Stop);
            }
            if attachment.has_event_from(&watchdog) {
                return Err("watchdog: no answer".to_owned());
            }
            Ok(Flow::Continue)
        })
        .expect("an answer");
    drop((health_guard, results_guard, watchdog));
    let answer = answer.expect("answer");
    assert_eq!(answer.status, LaserScanStatus::Ok, "{answer:?}");
    // The scan took longer than the hang timeout.
    let scan_ns = answer.scan_duration_ns;
    assert!(
        scan_ns > 12 * DEVICE_DELAY.as_nanos() as u64,
        "{scan_ns} ns"
    );
    assert!(scan_ns > HANG_TIMEOUT_NS, "{scan_ns} ns");

    // No gap between the request, the heartbeats and the answer near the hang timeout: the
    // runtime beats between the scan's exchanges.
    let mut stamps_ns: Vec<u64> = beats
        .iter()
        .map(|beat| beat.header.publish_ns)
        .filter(|&ns| ns >= sent_ns)
        .collect();
    stamps_ns.push(sent_ns);
    stamps_ns.push(answer.header.publish_ns);
    stamps_ns.sort_unstable();
    let largest_gap_ns = stamps_ns
        .windows(2)
        .map(|pair| pair[1] - pair[0])
        .max()
        .unwrap_or(0);
    assert!(
        largest_gap_ns < HANG_TIMEOUT_NS * 5 / 6,
        "heartbeat gap of {largest_gap_ns} ns during a scan of {scan_ns} ns"
    );
    assert!(
        beats
            .iter()
            .any(|beat| beat.detail.as_str() == "scanning_apple"
                && beat.detail_value == u64::from(request.apple_id)),
        "no heartbeat named the apple being scanned: {beats:?}"
    );

    laser.finish();
    // One scan: laser on, 5 x (move + capture), laser off.
    assert_eq!(device.finish(), 12);
}

#[test]
fn an_emergency_stop_mid_scan_ends_it_with_the_laser_off() {
    let domain = unique_domain("slowstop");
    let device = Device::start_slow(&domain, DEVICE_DELAY);
    let laser = Laser::start(&domain);
    let context = Context::new(&domain, "executive_test").expect("context");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let mut requests = context.publisher(LASER_SCAN_REQUEST).expect("requests");
    let results = context.subscriber(LASER_SCAN_RESULT).expect("results");
    let mut estop = context.publisher(EMERGENCY_STOP).expect("estop");
    wait_for(&health, is_laser);

    let request = request_in_reach(1);
    requests.publish(&request).expect("publish request");
    // Well into the scan: the heartbeat names the apple being scanned.
    wait_for(&health, |beat| {
        is_laser(beat) && beat.detail.as_str() == "scanning_apple"
    });
    let engaged_ns = MonotonicClock::read_ns();
    estop
        .publish(&EmergencyStop {
            engaged: 1,
            ..EmergencyStop::default()
        })
        .expect("engage");
    let answer = wait_for(&results, |r| r.request_seq == 1);
    assert_eq!(answer.status, LaserScanStatus::DeviceError, "{answer:?}");
    // Ended at the next tick: within the exchange under way and the stop's laser off.
    let latency_ns = answer.header.publish_ns.saturating_sub(engaged_ns);
    assert!(
        latency_ns < 2 * DEVICE_DELAY.as_nanos() as u64 + 1_000_000_000,
        "answered {latency_ns} ns after the stop"
    );

    // Released: the scan is not resumed, the device hears nothing more.
    estop.publish(&EmergencyStop::default()).expect("release");
    wait_for(&health, is_laser);
    laser.finish();
    let answered = device.finish();
    // Fewer than a whole scan's 12, the stop's laser off included.
    assert!(answered < 12, "{answered} device exchanges");
}
