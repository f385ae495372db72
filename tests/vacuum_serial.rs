//! The vacuum supervisor process driving the serial valve-board driver (`harvest vacuum --device
//! serial --port ...`) against the fake board on a pseudo-terminal: the same process the stack
//! runs on the robot, with its board reached over a real serial line. A board that falls silent
//! reaches `system/health` as a device error of kind timeout.

mod common;

use common::*;
use harvest_hw::valve_board::fake_board::{FakeBoard, FakeBoardConfig, FaultMode};
use harvest_ipc::catalogue::{PROCESS_HEALTH, VACUUM_STATE};
use harvest_ipc::payloads::{DeviceErrorCode, ProcessRunState};
use harvest_ipc::{Context, Domain};
use std::time::{Duration, Instant};

const WATCHDOG: Duration = Duration::from_secs(60);

#[test]
fn vacuum_process_reads_the_serial_board_and_publishes_its_pressures() {
    let _stack = one_stack_at_a_time();
    let board = FakeBoard::spawn(FakeBoardConfig::default()).expect("fake board on a pty");
    let domain_name = unique_domain("vser");
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "vacuum-serial-test").expect("node");
    let states = context.subscriber(VACUUM_STATE).expect("vacuum/state");
    let child = spawn_harvest(
        &domain_name,
        &["vacuum", "--device", "serial", "--port", board.port_path()],
    );

    let deadline = Instant::now() + WATCHDOG;
    let mut seen = 0;
    let mut last_source_mmh2o = 0.0f32;
    while seen < 20 && Instant::now() < deadline {
        while let Some(state) = states.receive().expect("receive") {
            seen += 1;
            last_source_mmh2o = state.pressure_mmh2o[2];
            // No arm asked for suction: both tubes stay cut from the source (valves 1 and 3).
            assert_eq!(
                [state.valve_open[0], state.valve_open[2]],
                [0, 0],
                "source valves of an idle stack"
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    );
    let (status, _, stderr) = wait_with_watchdog(child, WATCHDOG);
    assert!(
        seen >= 20,
        "vacuum/state from the serial board: {seen}; stderr:\n{stderr}"
    );
    // The fake board's source holds 2400 mmH2O with every gate closed (5 mmH2O noise).
    assert!(
        (last_source_mmh2o - 2400.0).abs() < 50.0,
        "source vacuum {last_source_mmh2o} mmH2O"
    );
    assert!(board.stats().requests > 20, "the driver polled the board");
    assert!(status.success(), "clean exit on SIGTERM; stderr:\n{stderr}");
    drop(states);
    drop(context);
    assert_eq!(leftover_files(&domain_name), "", "nothing left behind");
}

#[test]
fn a_missing_serial_port_is_named_in_the_error() {
    let domain_name = unique_domain("vnop");
    let (status, _, stderr) = run_harvest(
        &domain_name,
        &[
            "vacuum",
            "--device",
            "serial",
            "--port",
            "/dev/harvest-no-such-port",
        ],
        WATCHDOG,
    );
    assert!(!status.success());
    assert!(
        stderr.contains("/dev/harvest-no-such-port"),
        "stderr:\n{stderr}"
    );
    let (status, _, stderr) =
        run_harvest(&domain_name, &["vacuum", "--device", "serial"], WATCHDOG);
    assert!(!status.success());
    assert!(stderr.contains("--port"), "stderr:\n{stderr}");
    assert_eq!(leftover_files(&domain_name), "", "nothing left behind");
}

#[test]
fn a_silent_board_reaches_health_as_a_timeout() {
    let _stack = one_stack_at_a_time();
    let board = FakeBoard::spawn(FakeBoardConfig::default()).expect("fake board on a pty");
    let domain_name = unique_domain("vsil");
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "vacuum-silent-test").expect("node");
    let states = context.subscriber(VACUUM_STATE).expect("vacuum/state");
    let health = context.subscriber(PROCESS_HEALTH).expect("system/health");
    let child = spawn_harvest(
        &domain_name,
        &["vacuum", "--device", "serial", "--port", board.port_path()],
    );

    // Healthy first: the board answers and the heartbeats carry no device error.
    let deadline = Instant::now() + WATCHDOG;
    let mut healthy_beat = None;
    while healthy_beat.is_none() && Instant::now() < deadline {
        while states.receive().expect("receive").is_some() {}
        while let Some(beat) = health.receive().expect("receive") {
            if beat.process_name.as_str() == "vacuum"
                && beat.run_state.get() == Ok(ProcessRunState::Running)
            {
                healthy_beat = Some(beat.last_device_error.get());
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }

    // Then the board stops answering: the driver's timeouts reach the heartbeat by kind.
    board.set_fault_mode(FaultMode::Silent);
    let mut silent_beat = None;
    while silent_beat.is_none() && Instant::now() < deadline {
        while let Some(beat) = health.receive().expect("receive") {
            if beat.process_name.as_str() == "vacuum"
                && beat.last_device_error.get() != Ok(DeviceErrorCode::None)
            {
                silent_beat = Some((beat.last_device_error.get(), beat.run_state.get()));
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(child.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    );
    let (_, _, stderr) = wait_with_watchdog(child, WATCHDOG);
    assert_eq!(
        healthy_beat,
        Some(Ok(DeviceErrorCode::None)),
        "a running heartbeat before the fault; stderr:\n{stderr}"
    );
    assert_eq!(
        silent_beat,
        Some((Ok(DeviceErrorCode::Timeout), Ok(ProcessRunState::Degraded))),
        "the silent board in the heartbeat; stderr:\n{stderr}"
    );
    drop(states);
    drop(health);
    drop(context);
    assert_eq!(leftover_files(&domain_name), "", "nothing left behind");
}
