//! Device drivers against the simulated robot running as its own process (`harvest sim`), over
//! real shared memory: each simulated device passes the conformance suite written once for its
//! trait. The other implementations run the same suites elsewhere: the serial valve board
//! against the fake board (`hw/tests/valve_board_serial.rs`), the in-process platform stages
//! (sim crate), and here the evaluation's in-process servos.

mod common;

use common::*;
use harvest_eval::harvest::devices::{InProcessDeviceError, InProcessServos, SharedRobot};
use harvest_hw::arm_servos::conformance::{
    ServoConformanceConfig, conformance_suite as servo_suite,
};
use harvest_hw::arm_servos::sim::SimArmServos;
use harvest_hw::arm_servos::{ArmServos, JOINT_COUNT, JointFeedback};
use harvest_hw::conformance::{ConformanceReport, TestWatchdog};
use harvest_hw::lidar::conformance::{LidarConformanceConfig, conformance_suite as lidar_suite};
use harvest_hw::lidar::sim::SimLidar;
use harvest_hw::platform::conformance::{
    PlatformConformanceConfig, conformance_suite as platform_suite,
};
use harvest_hw::platform::sim::SimPlatform;
use harvest_hw::platform::{Platform, PlatformTravel};
use harvest_hw::rgbd_camera::conformance::{
    CameraConformanceConfig, conformance_suite as camera_suite,
};
use harvest_hw::rgbd_camera::sim::SimRgbdCamera;
use harvest_hw::valve_board::conformance::conformance_suite as valve_suite;
use harvest_hw::valve_board::sim::SimValveBoard;
use harvest_hw::{DeviceError, ErrorKind};
use harvest_ipc::{ArmId, Context, ManualClock};
use harvest_sim::robot::SimRobot;
use harvest_sim::scenario::Scenario;
use std::cell::RefCell;
use std::process::Child;
use std::rc::Rc;
use std::time::Duration;
use std::time::Instant;

/// Every test here aborts if it runs longer than this (a hung device exchange).
const WATCHDOG: Duration = Duration::from_secs(180);
/// The scenario the sim process runs (its camera and arms are what the drivers declare).
const SCENARIO: &str = "default";

struct SimProcess(Child);

impl SimProcess {
    fn start(domain: &str) -> Self {
        Self(spawn_harvest(
            domain,
            &["sim", "--scenario", SCENARIO, "--camera-rate-hz", "2"],
        ))
    }

    fn start_with_lidar(domain: &str) -> Self {
        Self(spawn_harvest(
            domain,
            &[
                "sim",
                "--scenario",
                SCENARIO,
                "--camera-rate-hz",
                "2",
                "--lidar",
            ],
        ))
    }
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        let _ = nix::sys::signal::kill(
            nix::unistd::Pid::from_raw(self.0.id() as i32),
            nix::sys::signal::Signal::SIGTERM,
        );
        let _ = self.0.wait();
    }
}

/// A running `harvest sim` in a domain of its own, and a node of the test in that domain.
struct SimDevices {
    context: Context,
    _sim: SimProcess,
    _domain: common::TestDomain,
}

impl SimDevices {
    fn start(tag: &str) -> Self {
        Self::start_with(tag, SimProcess::start)
    }

    fn start_with(tag: &str, start: fn(&str) -> SimProcess) -> Self {
        let domain_name = unique_domain(tag);
        let sim = start(&domain_name);
        let context = Context::new(domain_name.domain(), &format!("{tag}-test")).expect("node");
        Self {
            context,
            _sim: sim,
            _domain: domain_name,
        }
    }
}

fn assert_all_passed(report: &ConformanceReport, expected: usize) {
    assert_eq!(report.checks_passed.len(), expected, "{report:?}");
}

#[test]
fn simulated_valve_board_passes_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("valve board", WATCHDOG);
    let sim = SimDevices::start("valves");
    let report = valve_suite(|| {
        SimValveBoard::connect(&sim.context, Duration::from_secs(20))
            .expect("connect sim valve board")
    })
    .expect("conformance suite");
    assert_all_passed(&report, 7);
}

/// The joint limits the simulated arms enforce ([dual-arm Table 1], from the arm parameters).
fn declared_limits(arm: ArmId) -> [[f64; 2]; 4] {
    let scenario = Scenario::preset(SCENARIO).expect("scenario");
    let robot = SimRobot::new(&scenario, 1).expect("robot");
    let limits = robot.arm_params(arm).position_limits;
    let (min, max) = (limits.min.to_array(), limits.max.to_array());
    std::array::from_fn(|j| [min[j], max[j]])
}

#[test]
fn simulated_servos_of_both_arms_pass_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("servos", WATCHDOG);
    let sim = SimDevices::start("servo");
    for arm in ArmId::ALL {
        let limits = declared_limits(arm);
        let config = ServoConformanceConfig::with_limits(limits);
        let report = servo_suite(&config, || {
            SimArmServos::connect(&sim.context, arm, limits).expect("connect sim servos")
        })
        .unwrap_or_else(|error| panic!("arm {arm:?}: {error}"));
        assert_all_passed(&report, 4);
    }
}

#[test]
fn simulated_camera_passes_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("camera", WATCHDOG);
    let sim = SimDevices::start("camera");
    // The silent camera: the same driver in a domain where no device runs.
    let silent_domain = unique_domain("nocam");
    let silent_context = Context::new(silent_domain.domain(), "silent-camera-test").expect("node");
    let camera = Scenario::preset(SCENARIO).expect("scenario").camera;
    let config = CameraConformanceConfig {
        rgb_intrinsics: camera.color_intrinsics(),
        depth_intrinsics: camera.depth_intrinsics(),
        ..CameraConformanceConfig::tl460()
    };
    let report = camera_suite(
        &config,
        || SimRgbdCamera::connect(&sim.context).expect("connect sim camera"),
        || SimRgbdCamera::connect(&silent_context).expect("connect silent camera"),
    )
    .expect("conformance suite");
    assert_all_passed(&report, 3);
}

#[test]
fn simulated_lidar_passes_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("lidar", WATCHDOG);
    let sim = SimDevices::start_with("lidar", SimProcess::start_with_lidar);
    // The silent LiDAR: the same driver in a domain where no device runs.
    let silent_domain = unique_domain("nolidar");
    let silent_context = Context::new(silent_domain.domain(), "silent-lidar-test").expect("node");
    let integration = Duration::from_millis(500);
    let report = lidar_suite(
        &LidarConformanceConfig::mid70(integration),
        || SimLidar::connect(&sim.context, integration).expect("connect sim lidar"),
        || SimLidar::connect(&silent_context, integration).expect("connect silent lidar"),
    )
    .expect("conformance suite");
    assert_all_passed(&report, 4);
}

#[test]
fn simulated_platform_passes_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("platform", WATCHDOG);
    let sim = SimDevices::start("platform");
    let report = platform_suite(&PlatformConformanceConfig::default(), || {
        SimPlatform::connect(
            &sim.context,
            PlatformTravel::default(),
            Duration::from_secs(20),
        )
        .expect("connect sim platform")
    })
    .expect("conformance suite");
    assert_all_passed(&report, 5);
}

#[test]
fn platform_driver_without_a_device_reports_a_timeout() {
    let _watchdog = TestWatchdog::arm("platform timeout", WATCHDOG);
    let domain = unique_domain("noplat");
    let context = Context::new(domain.domain(), "silent-platform-test").expect("node");
    let mut platform = SimPlatform::connect(
        &context,
        PlatformTravel::default(),
        Duration::from_millis(50),
    )
    .expect("connect");
    let error = platform.position().expect_err("no device is running");
    assert_eq!(error.kind(), ErrorKind::Timeout, "{error}");
    // Refused before reaching the (absent) device.
    let error = platform.move_to(0.1, 2.0).expect_err("beyond the travel");
    assert_eq!(error.kind(), ErrorKind::InvalidRequest, "{error}");
    assert!(error.to_string().contains("up-down"), "{error}");
}

/// The evaluation's in-process servos over a [`SimRobot`] of this thread, with the robot and its
/// clock advanced by the host time elapsed before every call (the evaluation steps them itself).
struct HostTimedServos {
    servos: InProcessServos,
    robot: SharedRobot,
    clock: ManualClock,
    last_step: Instant,
}

impl HostTimedServos {
    fn advance(&mut self) {
        let elapsed = self.last_step.elapsed();
        self.last_step = Instant::now();
        self.robot
            .borrow_mut()
            .step(elapsed.as_secs_f64())
            .expect("robot step");
        self.clock.advance_ns(elapsed.as_nanos() as u64);
    }
}

impl ArmServos for HostTimedServos {
    type Error = InProcessDeviceError;

    fn command(
        &mut self,
        position: [f64; JOINT_COUNT],
        velocity: [f64; JOINT_COUNT],
    ) -> Result<(), Self::Error> {
        self.advance();
        self.servos.command(position, velocity)
    }

    fn hold(&mut self) -> Result<(), Self::Error> {
        self.advance();
        self.servos.hold()
    }

    fn feedback(&mut self) -> Result<Option<JointFeedback>, Self::Error> {
        self.advance();
        self.servos.feedback()
    }
}

#[test]
fn in_process_servos_pass_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("in-process servos", WATCHDOG);
    let scenario = Scenario::preset(SCENARIO).expect("scenario");
    let robot: SharedRobot = Rc::new(RefCell::new(SimRobot::new(&scenario, 1).expect("robot")));
    let clock = ManualClock::starting_at(1);
    for arm in [ArmId::Arm1, ArmId::Arm2] {
        let limits = declared_limits(arm);
        let config = ServoConformanceConfig::with_limits(limits);
        let report = servo_suite(&config, || HostTimedServos {
            servos: InProcessServos::new(robot.clone(), arm, clock.clone()),
            robot: robot.clone(),
            clock: clock.clone(),
            last_step: Instant::now(),
        })
        .unwrap_or_else(|error| panic!("{arm:?}: {error}"));
        assert_all_passed(&report, 4);
    }
}
