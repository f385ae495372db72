//! Device drivers against the simulated robot running as its own process (`harvest sim`), over
//! real shared memory: the valve board passes the same conformance suite as the serial driver,
//! and an arm's servos follow a set-point.

mod common;

use common::*;
use harvest_hw::arm_servos::ArmServos;
use harvest_hw::arm_servos::sim::SimArmServos;
use harvest_hw::valve_board::conformance::conformance_suite;
use harvest_hw::valve_board::sim::SimValveBoard;
use harvest_ipc::{ArmId, Context, Domain};
use std::process::Child;
use std::time::{Duration, Instant};

struct SimProcess(Child);

impl SimProcess {
    fn start(domain: &str) -> Self {
        Self(spawn_harvest(domain, &["sim", "--camera-rate-hz", "2"]))
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

#[test]
fn simulated_valve_board_passes_the_conformance_suite() {
    let domain_name = unique_domain("valves");
    let _sim = SimProcess::start(&domain_name);
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "valve-test").expect("node");
    let report = conformance_suite(|| {
        SimValveBoard::connect(&context, Duration::from_secs(20)).expect("connect sim valve board")
    })
    .expect("conformance suite");
    assert_eq!(report.checks_passed.len(), 7, "{report:?}");
}

#[test]
fn simulated_servos_follow_a_setpoint() {
    let domain_name = unique_domain("servo");
    let _sim = SimProcess::start(&domain_name);
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "servo-test").expect("node");
    let limits = [[-1.0, 1.0], [-3.2, 3.2], [-3.2, 3.2], [-3.2, 3.2]];
    let mut servos = SimArmServos::connect(&context, ArmId::One, limits).expect("connect");
    // Out-of-limit and NaN set-points are refused before reaching the device.
    assert!(servos.command([5.0, 0.0, 0.0, 0.0], [0.0; 4]).is_err());
    assert!(servos.command([f64::NAN, 0.0, 0.0, 0.0], [0.0; 4]).is_err());
    let deadline = Instant::now() + Duration::from_secs(30);
    let target_twist_rad = 0.5;
    loop {
        servos
            .command([0.0, 0.0, 0.0, target_twist_rad], [0.0; 4])
            .expect("command");
        if let Some(feedback) = servos.feedback().expect("feedback")
            && (feedback.position[3] - target_twist_rad).abs() < 0.01
        {
            assert!(feedback.capture_ns > 0);
            break;
        }
        assert!(
            Instant::now() < deadline,
            "servo never reached the set-point"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}
