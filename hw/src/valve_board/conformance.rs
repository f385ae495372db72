//! Behaviour every [`ValveBoard`] implementation must show, written once and generic over the
//! trait: run it from a test with a factory of fresh boards, e.g.
//!
//! ```ignore
//! #[test]
//! fn my_board_conforms() -> Result<(), ConformanceError> {
//!     let _watchdog = TestWatchdog::arm("my_board_conforms", Duration::from_secs(30));
//!     conformance_suite(|| MyBoard::new()).map(|_| ())
//! }
//! ```
//!
//! Each check gets its own board from the factory. Waits are bounded by
//! [`ConformanceConfig::settle_timeout`] (a liveness bound well above the 1 s actuation time,
//! not a timing assertion); a check failure is returned as [`ConformanceError`] naming the check
//! and what was observed.

use super::types::{PressureReadings, ValveId, ValveState, ValveStates};
use super::{VALVE_COUNT, ValveBoard};
use crate::conformance::{Check, PollBounds, Probe, call, poll_until, run_checks, violated};
use crate::error_kind::{DeviceError, ErrorKind};
use std::time::Duration;

/// The shared harness's types, re-exported where this suite's users have always found them.
pub use crate::conformance::{ConformanceError, ConformanceReport, TestWatchdog};

/// Bounds of the conformance run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConformanceConfig {
    /// Longest wait for valves to reach their end stops after a command.
    pub settle_timeout: Duration,
    /// Pause between two state polls while waiting.
    pub poll_interval: Duration,
    /// Pressure samples read in the pressure check.
    pub pressure_samples: usize,
}

impl Default for ConformanceConfig {
    fn default() -> Self {
        ConformanceConfig {
            settle_timeout: Duration::from_secs(5),
            poll_interval: Duration::from_millis(10),
            pressure_samples: 20,
        }
    }
}

/// Run every check with the default bounds.
pub fn conformance_suite<B: ValveBoard>(
    make: impl FnMut() -> B,
) -> Result<ConformanceReport, ConformanceError> {
    conformance_suite_with(ConformanceConfig::default(), make)
}

/// Run every check, each on a fresh board from `make`.
pub fn conformance_suite_with<B: ValveBoard>(
    config: ConformanceConfig,
    make: impl FnMut() -> B,
) -> Result<ConformanceReport, ConformanceError> {
    let checks: [Check<ConformanceConfig, B>; 7] = [
        ("heartbeat", check_heartbeat),
        ("close_all_settles_closed", check_close_all_settles),
        ("each_valve_opens_and_closes_alone", check_each_valve),
        ("set_is_idempotent", check_set_idempotent),
        ("invalid_valve_rejected", check_invalid_valve),
        ("pressures_plausible", check_pressures),
        ("close_all_from_mixed_states", check_close_all_mixed),
    ];
    run_checks("valve board", &config, &checks, make, |name, board| {
        let faults = board.take_faults();
        if faults.is_empty() {
            Ok(())
        } else {
            Err(violated(
                name,
                format!("healthy board reported faults {faults:?}"),
            ))
        }
    })
}

/// Poll valve states until `done` holds, every intermediate state satisfying `allowed`.
fn wait_for<B: ValveBoard>(
    check: &'static str,
    config: &ConformanceConfig,
    board: &mut B,
    what: &str,
    allowed: impl Fn(ValveId, ValveState) -> bool,
    done: impl Fn(&ValveStates) -> bool,
) -> Result<ValveStates, ConformanceError> {
    let bounds = PollBounds {
        timeout: config.settle_timeout,
        interval: config.poll_interval,
    };
    poll_until(check, bounds, what, || {
        let states = call(check, || "valve_states()".to_owned(), board.valve_states())?;
        if let Some((valve, state)) = states.iter().find(|&(v, s)| !allowed(v, s)) {
            return Err(violated(
                check,
                format!("while waiting for {what}, {valve} was {state:?} (all: {states:?})"),
            ));
        }
        Ok(if done(&states) {
            Probe::Done(states)
        } else {
            Probe::Waiting(format!("states {states:?}"))
        })
    })
}

fn all_closed(states: &ValveStates) -> bool {
    states.0.iter().all(|s| s.is_closed())
}

/// Close everything and wait; any intermediate state except `Stuck` is allowed since the
/// board's initial state is unknown.
fn close_all_and_settle<B: ValveBoard>(
    check: &'static str,
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    call(check, || "close_all()".to_owned(), board.close_all())?;
    wait_for(
        check,
        config,
        board,
        "all valves closed",
        |_, s| s != ValveState::Stuck,
        all_closed,
    )
    .map(|_| ())
}

/// `set_valve(valve, open)`; a failure names the call.
fn set_valve<B: ValveBoard>(
    check: &'static str,
    board: &mut B,
    valve: ValveId,
    open: bool,
) -> Result<(), ConformanceError> {
    let position = if open { "open" } else { "closed" };
    call(
        check,
        || format!("set_valve({}, {position})", valve.0),
        board.set_valve(valve, open),
    )
}

/// Waits until `valve` is open; meanwhile no valve may be `Stuck`.
fn wait_open<B: ValveBoard>(
    check: &'static str,
    config: &ConformanceConfig,
    board: &mut B,
    valve: ValveId,
) -> Result<(), ConformanceError> {
    wait_for(
        check,
        config,
        board,
        &format!("{valve} open"),
        |_, s| s != ValveState::Stuck,
        |states| states.get(valve) == Some(ValveState::Open),
    )
    .map(|_| ())
}

/// Commands `valve` alone to `open` and waits until it is there; meanwhile it may only be
/// moving that way and every other valve stays closed.
fn move_alone<B: ValveBoard>(
    check: &'static str,
    config: &ConformanceConfig,
    board: &mut B,
    valve: ValveId,
    open: bool,
) -> Result<(), ConformanceError> {
    set_valve(check, board, valve, open)?;
    let (moving, end, position) = if open {
        (ValveState::Opening, ValveState::Open, "open")
    } else {
        (ValveState::Closing, ValveState::Closed, "closed")
    };
    wait_for(
        check,
        config,
        board,
        &format!("{valve} {position}"),
        |v, s| {
            if v == valve {
                s == moving || s == end
            } else {
                s.is_closed()
            }
        },
        |states| states.get(valve) == Some(end),
    )
    .map(|_| ())
}

/// Two heartbeats succeed and the board clock does not run backwards.
fn check_heartbeat<B: ValveBoard>(
    _config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "heartbeat";
    let first = call(CHECK, || "ping()".to_owned(), board.ping())?;
    let second = call(CHECK, || "ping()".to_owned(), board.ping())?;
    if second.board_uptime_ms < first.board_uptime_ms {
        return Err(violated(
            CHECK,
            format!(
                "board uptime went back from {} ms to {} ms",
                first.board_uptime_ms, second.board_uptime_ms
            ),
        ));
    }
    Ok(())
}

/// After `close_all` every valve reaches `Closed`, passing only through `Closing`.
fn check_close_all_settles<B: ValveBoard>(
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    close_all_and_settle("close_all_settles_closed", config, board)
}

/// Each valve, commanded alone, goes Closed -> (Opening) -> Open -> (Closing) -> Closed while
/// the other three stay closed.
fn check_each_valve<B: ValveBoard>(
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "each_valve_opens_and_closes_alone";
    close_all_and_settle(CHECK, config, board)?;
    for valve in ValveId::ALL {
        move_alone(CHECK, config, board, valve, true)?;
        move_alone(CHECK, config, board, valve, false)?;
    }
    Ok(())
}

/// Commanding an open valve open again leaves it open (never `Closing`/`Closed`), and
/// commanding a closed valve closed leaves it closed.
fn check_set_idempotent<B: ValveBoard>(
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "set_is_idempotent";
    close_all_and_settle(CHECK, config, board)?;
    let valve = ValveId(2);
    set_valve(CHECK, board, valve, true)?;
    wait_open(CHECK, config, board, valve)?;
    for _ in 0..3 {
        set_valve(CHECK, board, valve, true)?;
        set_valve(CHECK, board, ValveId(1), false)?;
        let states = call(CHECK, || "valve_states()".to_owned(), board.valve_states())?;
        let expected = ValveStates([
            ValveState::Closed,
            ValveState::Open,
            ValveState::Closed,
            ValveState::Closed,
        ]);
        if states != expected {
            return Err(violated(
                CHECK,
                format!("repeating commands changed states to {states:?}, expected {expected:?}"),
            ));
        }
    }
    Ok(())
}

/// Ids 0 and 5.. are refused with `InvalidRequest` and change nothing; the board keeps
/// answering.
fn check_invalid_valve<B: ValveBoard>(
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "invalid_valve_rejected";
    close_all_and_settle(CHECK, config, board)?;
    for bad in [0u8, VALVE_COUNT as u8 + 1, u8::MAX] {
        for open in [true, false] {
            match board.set_valve(ValveId(bad), open) {
                Err(e) if e.kind() == ErrorKind::InvalidRequest => {}
                other => {
                    return Err(ConformanceError::WrongOutcome {
                        check: CHECK,
                        call: format!("set_valve({bad}, {open})"),
                        expected: ErrorKind::InvalidRequest,
                        got: match other {
                            Ok(()) => "Ok".to_owned(),
                            Err(e) => format!("{:?}: {e}", e.kind()),
                        },
                    });
                }
            }
        }
    }
    let states = call(CHECK, || "valve_states()".to_owned(), board.valve_states())?;
    if !all_closed(&states) {
        return Err(violated(
            CHECK,
            format!("refused requests changed valve states to {states:?}"),
        ));
    }
    call(CHECK, || "ping()".to_owned(), board.ping())?;
    Ok(())
}

/// Pressure samples are finite and physically plausible, with the arms vented or closed and
/// with arm 1 open to the source.
fn check_pressures<B: ValveBoard>(
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "pressures_plausible";
    let sample = |board: &mut B| -> Result<(), ConformanceError> {
        for _ in 0..config.pressure_samples.max(1) {
            let p: PressureReadings = call(CHECK, || "pressures()".to_owned(), board.pressures())?;
            if !p.is_plausible() {
                return Err(violated(CHECK, format!("implausible reading {p:?}")));
            }
        }
        Ok(())
    };
    close_all_and_settle(CHECK, config, board)?;
    sample(board)?;
    set_valve(CHECK, board, ValveId(1), true)?;
    sample(board)?;
    wait_open(CHECK, config, board, ValveId(1))?;
    sample(board)
}

/// `close_all` issued while valves are open or still moving closes all of them; repeating
/// it is harmless.
fn check_close_all_mixed<B: ValveBoard>(
    config: &ConformanceConfig,
    board: &mut B,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "close_all_from_mixed_states";
    close_all_and_settle(CHECK, config, board)?;
    set_valve(CHECK, board, ValveId(1), true)?;
    wait_open(CHECK, config, board, ValveId(1))?;
    set_valve(CHECK, board, ValveId(4), true)?;
    // Two `close_all` in a row: this one and the one that settles.
    call(CHECK, || "close_all()".to_owned(), board.close_all())?;
    close_all_and_settle(CHECK, config, board)
}
