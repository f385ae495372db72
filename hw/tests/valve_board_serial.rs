//! The real serial valve board driver against the fake board on a pseudo-terminal: the generic
//! conformance suite, then driver-specific fault handling (garbage, silence, corrupt
//! checksums, late replies, disconnects, stuck valves, invalid ids).
//!
//! Every test arms a watchdog that aborts the process after 30 s, and every driver call is
//! bounded by its per-request timeout times its attempts.

use harvest_hw::valve_board::conformance::{
    ConformanceConfig, ConformanceError, TestWatchdog, conformance_suite_with,
};
use harvest_hw::valve_board::fake_board::{FakeBackedBoard, FakeBoard, FakeBoardConfig, FaultMode};
use harvest_hw::valve_board::{
    BoardFault, ErasedValveBoard, PressureSensor, SerialBoardConfig, SerialValveBoard, ValveBoard,
    ValveId, ValveState,
};
use harvest_hw::{DeviceError, ErrorKind};
use std::time::{Duration, Instant};

const WATCHDOG: Duration = Duration::from_secs(30);

/// Fast valves so the suite runs in a few seconds.
fn fake_config() -> FakeBoardConfig {
    FakeBoardConfig {
        actuation_ms: 60,
        stuck_detect_ms: 150,
        ..FakeBoardConfig::default()
    }
}

/// Generous per-attempt timeout: the machine is shared, and healthy tests must not depend on
/// scheduling luck (the retry path is tested on purpose below).
fn driver_config() -> SerialBoardConfig {
    SerialBoardConfig {
        request_timeout_ms: 250,
        max_attempts: 3,
        boot_timeout_ms: 2_000,
        ..SerialBoardConfig::new("set by the fake")
    }
}

fn connect() -> FakeBackedBoard {
    FakeBoard::spawn_with_driver(fake_config(), &driver_config())
        .expect("driver connects to fake board")
}

/// Poll until `valve` reads `want`, for at most 5 s.
fn wait_state(board: &mut impl ValveBoard, valve: ValveId, want: ValveState) {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let states = board.valve_states().expect("valve_states");
        if states.get(valve) == Some(want) {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "{valve} never reached {want:?}: {states:?}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn serial_driver_passes_conformance_suite() -> Result<(), ConformanceError> {
    let _watchdog = TestWatchdog::arm("serial_driver_passes_conformance_suite", WATCHDOG);
    let report = conformance_suite_with(ConformanceConfig::default(), connect)?;
    assert_eq!(report.checks_passed.len(), 7, "{report:?}");
    Ok(())
}

#[test]
fn erased_board_passes_conformance_suite() -> Result<(), ConformanceError> {
    let _watchdog = TestWatchdog::arm("erased_board_passes_conformance_suite", WATCHDOG);
    let report = conformance_suite_with(ConformanceConfig::default(), || {
        ErasedValveBoard::boxed(connect())
    })?;
    assert_eq!(report.checks_passed.len(), 7);
    Ok(())
}

#[test]
fn driver_over_taken_port_without_handshake() {
    let _watchdog = TestWatchdog::arm("driver_over_taken_port_without_handshake", WATCHDOG);
    let mut fake = FakeBoard::spawn(fake_config()).expect("fake board");
    let port = fake.take_port().expect("slave port");
    let mut board = SerialValveBoard::with_port(Box::new(port), &driver_config());
    let first = board.ping().expect("ping");
    board.set_valve(ValveId(3), true).expect("set");
    wait_state(&mut board, ValveId(3), ValveState::Open);
    let p = board.pressures().expect("pressures");
    // Fake model: arm 2's source gate (valve 3) open, its vent (valve 4) closed, so arm 2
    // sees most of the source vacuum; arm 1 is closed off and reads only noise.
    assert!(p.is_plausible(), "{p:?}");
    assert!(p.arm2_vacuum_mmh2o > 1000.0, "{p:?}");
    assert!(p.arm1_vacuum_mmh2o.abs() < 50.0, "{p:?}");
    assert!(
        (p.arm2_vacuum_mmh2o - p.source_vacuum_mmh2o).abs() < 50.0,
        "{p:?}"
    );
    let second = board.ping().expect("ping");
    assert!(second.board_uptime_ms >= first.board_uptime_ms);
    assert_eq!(board.stats().retries, 0);
}

#[test]
fn garbage_between_lines_is_skipped_without_retries() {
    let _watchdog = TestWatchdog::arm("garbage_between_lines", WATCHDOG);
    let mut board = connect();
    board.fake.set_fault_mode(FaultMode::Garbage);
    for i in 0..10u8 {
        board.driver.ping().expect("ping through garbage");
        let valve = ValveId(i % 4 + 1);
        board
            .driver
            .set_valve(valve, i % 2 == 0)
            .expect("set through garbage");
        board.driver.valve_states().expect("states through garbage");
        let p = board.driver.pressures().expect("pressures through garbage");
        assert!(p.is_plausible(), "{p:?}");
    }
    let stats = board.driver.stats();
    // Each reply was preceded by a cut frame, a bad-checksum line and an overlong line.
    assert!(stats.bad_lines >= 3 * 40, "{stats:?}");
    assert!(stats.noise_bytes > 40 * 3, "{stats:?}");
    assert_eq!(stats.retries, 0, "{stats:?}");
    // Handshake ping included on both sides.
    assert_eq!(stats.requests, board.fake.stats().requests, "{stats:?}");
    assert!(board.driver.take_faults().is_empty());
}

#[test]
fn silent_board_times_out_after_all_attempts_then_recovers() {
    let _watchdog = TestWatchdog::arm("silent_board_times_out", WATCHDOG);
    let mut board = connect();
    let before = board.fake.stats().requests;
    board.fake.set_fault_mode(FaultMode::Silent);
    let error = board.driver.ping().expect_err("silent board must time out");
    assert_eq!(error.kind(), ErrorKind::Timeout, "{error}");
    assert!(error.to_string().contains("3 attempt(s)"), "{error}");
    // Every attempt reached the board.
    assert_eq!(board.fake.stats().requests - before, 3);
    assert_eq!(board.driver.stats().retries, 2);
    board.fake.set_fault_mode(FaultMode::Healthy);
    board.driver.ping().expect("board answers again");
}

#[test]
fn one_corrupt_reply_is_retried() {
    let _watchdog = TestWatchdog::arm("one_corrupt_reply_is_retried", WATCHDOG);
    let mut board = connect();
    board.fake.set_fault_mode_for(FaultMode::CorruptChecksum, 1);
    let states = board
        .driver
        .valve_states()
        .expect("second attempt succeeds");
    assert!(states.0.iter().all(|s| s.is_closed()), "{states:?}");
    let stats = board.driver.stats();
    assert_eq!(stats.retries, 1, "{stats:?}");
    assert_eq!(stats.bad_lines, 1, "{stats:?}");
}

#[test]
fn corrupt_replies_give_protocol_error() {
    let _watchdog = TestWatchdog::arm("corrupt_replies_give_protocol_error", WATCHDOG);
    let mut board = connect();
    board.fake.set_fault_mode(FaultMode::CorruptChecksum);
    let error = board.driver.pressures().expect_err("no valid reply");
    assert_eq!(error.kind(), ErrorKind::Protocol, "{error}");
    assert!(error.to_string().contains("checksum"), "{error}");
    board.fake.set_fault_mode(FaultMode::Healthy);
    board.driver.pressures().expect("recovers");
}

#[test]
fn late_reply_to_an_earlier_attempt_is_dropped() {
    let _watchdog = TestWatchdog::arm("late_reply_is_dropped", WATCHDOG);
    let fake = FakeBoard::spawn(fake_config()).expect("fake");
    let config = SerialBoardConfig {
        path: fake.port_path().to_owned(),
        request_timeout_ms: 100,
        max_attempts: 6,
        ..driver_config()
    };
    let mut driver = SerialValveBoard::open(&config).expect("open");
    // The reply to the first attempt comes 250 ms late, after that attempt's 100 ms
    // deadline, so it must be recognised by its sequence number and dropped.
    fake.set_fault_mode_for(FaultMode::Late { delay_ms: 250 }, 1);
    driver
        .set_valve(ValveId(2), true)
        .expect("a later attempt succeeds");
    let stats = driver.stats();
    assert!(stats.retries >= 1, "{stats:?}");
    assert!(stats.stale_replies >= 1, "{stats:?}");
    drop(driver);
    drop(fake);
}

#[test]
fn disconnect_gives_disconnected_kind_and_stays_disconnected() {
    let _watchdog = TestWatchdog::arm("disconnect_gives_disconnected", WATCHDOG);
    let mut board = connect();
    board.driver.ping().expect("connected");
    board.fake.disconnect();
    let error = board.driver.ping().expect_err("board gone");
    assert_eq!(error.kind(), ErrorKind::Disconnected, "{error}");
    let again = board.driver.close_all().expect_err("still gone");
    assert_eq!(again.kind(), ErrorKind::Disconnected, "{again}");
    assert!(again.to_string().contains("reopen"), "{again}");
}

#[test]
fn disconnect_while_waiting_for_reply() {
    let _watchdog = TestWatchdog::arm("disconnect_while_waiting", WATCHDOG);
    let slow = SerialBoardConfig {
        request_timeout_ms: 5_000,
        max_attempts: 1,
        ..driver_config()
    };
    let FakeBackedBoard {
        mut driver,
        mut fake,
    } = FakeBoard::spawn_with_driver(fake_config(), &slow).expect("connect");
    fake.set_fault_mode(FaultMode::Silent);
    let closer = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(100));
        fake.disconnect();
        fake
    });
    // Waiting on a 5 s attempt when the master closes: the hang-up ends the wait early with
    // Disconnected, not Timeout.
    let error = driver.pressures().expect_err("hang-up");
    assert_eq!(error.kind(), ErrorKind::Disconnected, "{error}");
    drop(closer.join().expect("closer thread"));
}

#[test]
fn invalid_valve_is_refused_without_touching_the_line() {
    let _watchdog = TestWatchdog::arm("invalid_valve_refused", WATCHDOG);
    let mut board = connect();
    let board_requests = board.fake.stats().requests;
    let driver_requests = board.driver.stats().requests;
    for bad in [0u8, 5, 200] {
        let error = board
            .driver
            .set_valve(ValveId(bad), true)
            .expect_err("invalid id");
        assert_eq!(error.kind(), ErrorKind::InvalidRequest, "{error}");
        assert!(
            error.to_string().contains(&format!("valve {bad}")),
            "{error}"
        );
    }
    assert_eq!(board.fake.stats().requests, board_requests);
    assert_eq!(board.driver.stats().requests, driver_requests);
    assert_eq!(board.fake.stats().rejected_lines, 0);
}

#[test]
fn stuck_valve_reports_fault_and_refuses_commands() {
    let _watchdog = TestWatchdog::arm("stuck_valve", WATCHDOG);
    let mut board = connect();
    board.fake.stick_valve(ValveId(3));
    board
        .driver
        .set_valve(ValveId(3), true)
        .expect("command accepted before the jam is detected");
    wait_state(&mut board.driver, ValveId(3), ValveState::Stuck);
    assert_eq!(
        board.driver.take_faults(),
        vec![BoardFault::ValveStuck(ValveId(3))]
    );
    assert!(board.driver.take_faults().is_empty(), "faults are drained");
    let error = board
        .driver
        .set_valve(ValveId(3), false)
        .expect_err("stuck valve refused");
    assert_eq!(error.kind(), ErrorKind::Fault, "{error}");
    // The other valves still work.
    board.driver.set_valve(ValveId(1), true).expect("valve 1");
    wait_state(&mut board.driver, ValveId(1), ValveState::Open);
}

#[test]
fn unsolicited_faults_are_queued_in_order() {
    let _watchdog = TestWatchdog::arm("unsolicited_faults", WATCHDOG);
    let mut board = connect();
    board.fake.emit_fault(BoardFault::SupplyLow);
    board
        .fake
        .emit_fault(BoardFault::SensorFault(PressureSensor::Arm2));
    board.fake.emit_fault(BoardFault::BoardReset);
    board.driver.ping().expect("ping");
    assert_eq!(
        board.driver.take_faults(),
        vec![
            BoardFault::SupplyLow,
            BoardFault::SensorFault(PressureSensor::Arm2),
            BoardFault::BoardReset
        ]
    );
    assert_eq!(board.driver.stats().faults, 3);
}

#[test]
fn open_nonexistent_port_is_disconnected_kind() {
    let _watchdog = TestWatchdog::arm("open_nonexistent_port", WATCHDOG);
    let error = SerialValveBoard::open(&SerialBoardConfig::new("/dev/does-not-exist-valve-board"))
        .expect_err("no such port");
    assert_eq!(error.kind(), ErrorKind::Disconnected, "{error}");
    assert!(
        error
            .to_string()
            .contains("/dev/does-not-exist-valve-board")
    );
}

/// Round-trip latency of a ping over the pty, reported (not asserted). Run with
/// `cargo test -p harvest-hw --test valve_board_serial -- --nocapture ping_round_trip`.
#[test]
fn ping_round_trip_report() {
    let _watchdog = TestWatchdog::arm("ping_round_trip_report", WATCHDOG);
    let mut board = connect();
    let mut samples_us: Vec<u128> = (0..500)
        .map(|_| {
            let t = Instant::now();
            board.driver.ping().expect("ping");
            t.elapsed().as_micros()
        })
        .collect();
    samples_us.sort_unstable();
    let pct = |q: f64| samples_us[((samples_us.len() - 1) as f64 * q) as usize];
    eprintln!(
        "valve board ping over pty: n={} p50={} us p99={} us max={} us",
        samples_us.len(),
        pct(0.5),
        pct(0.99),
        pct(1.0)
    );
}
