//! The stop always wins in the vacuum supervisor: its real control loop over real shared
//! memory, its valve board a double whose reads and writes fail on command. An emergency stop
//! engaged while every board read fails closes every valve within one period; a refused
//! close is sent again every period until the board takes it; a failed read alone closes
//! nothing (a carried apple is not dropped); a loop that ends on board errors leaves the
//! valves closed.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup is a failed test

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_hw::error_kind::{DeviceError, ErrorKind};
use harvest_hw::valve_board::{
    BoardFault, Heartbeat, PressureReadings, ValveBoard, ValveId, ValveState, ValveStates,
};
use harvest_ipc::catalogue::{EMERGENCY_STOP, VACUUM_STATE};
use harvest_ipc::payloads::EmergencyStop;
use harvest_ipc::{Context, MonotonicClock, ScratchDomain};
use harvest_robot_model::ArmId;
use harvest_runtime::RunError;
use harvest_vacuum::node::{VacuumNode, VacuumNodeConfig};
use harvest_vacuum_process::policy_arg::PolicyArg;
use harvest_vacuum_process::process::{
    VacuumArgs, VacuumDevice, VacuumProcessConfig, VacuumProcessError, control_loop,
};

const WATCHDOG: Duration = Duration::from_secs(30);

#[derive(Debug, thiserror::Error)]
#[error("board exchange failed (injected)")]
struct Injected;

impl DeviceError for Injected {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Timeout
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Call {
    Read,
    SetValve,
    CloseAll,
}

#[derive(Debug, Default)]
struct Shared {
    fail_reads: AtomicBool,
    fail_writes: AtomicBool,
    calls: Mutex<Vec<(u64, Call, bool)>>,
}

/// An ideal board (valves where last commanded, no vacuum) that fails on command.
struct Board {
    shared: Arc<Shared>,
    open: [bool; 4],
}

impl Board {
    fn log(&self, call: Call, fail: &AtomicBool) -> Result<(), Injected> {
        let failed = fail.load(Ordering::SeqCst);
        let at_ns = MonotonicClock::read_ns();
        self.shared
            .calls
            .lock()
            .unwrap()
            .push((at_ns, call, !failed));
        if failed { Err(Injected) } else { Ok(()) }
    }
}

impl ValveBoard for Board {
    type Error = Injected;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Injected> {
        self.log(Call::SetValve, &self.shared.fail_writes)?;
        if let Some(i) = valve.index() {
            self.open[i] = open;
        }
        Ok(())
    }

    fn valve_states(&mut self) -> Result<ValveStates, Injected> {
        self.log(Call::Read, &self.shared.fail_reads)?;
        Ok(ValveStates(self.open.map(|open| {
            if open {
                ValveState::Open
            } else {
                ValveState::Closed
            }
        })))
    }

    fn pressures(&mut self) -> Result<PressureReadings, Injected> {
        Ok(PressureReadings {
            arm1_vacuum_mmh2o: 0.0,
            arm2_vacuum_mmh2o: 0.0,
            source_vacuum_mmh2o: 0.0,
        })
    }

    fn close_all(&mut self) -> Result<(), Injected> {
        self.log(Call::CloseAll, &self.shared.fail_writes)?;
        self.open = [false; 4];
        Ok(())
    }

    fn ping(&mut self) -> Result<Heartbeat, Injected> {
        Ok(Heartbeat { board_uptime_ms: 0 })
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        Vec::new()
    }
}

fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < WATCHDOG, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The calls from each board read after `after_ns` to the next read (the last, unfinished
/// period left out).
fn periods_after(shared: &Shared, after_ns: u64) -> Vec<Vec<(Call, bool)>> {
    let mut periods: Vec<Vec<(Call, bool)>> = Vec::new();
    for &(at_ns, call, ok) in shared.calls.lock().unwrap().iter() {
        if at_ns <= after_ns {
            continue;
        }
        match call {
            Call::Read => periods.push(vec![(call, ok)]),
            _ => {
                if let Some(period) = periods.last_mut() {
                    period.push((call, ok));
                }
            }
        }
    }
    periods.pop();
    periods
}

#[test]
fn an_emergency_stop_during_board_errors_closes_every_valve_within_one_period() {
    let domain = ScratchDomain::new("vacstop");
    let shared = Arc::new(Shared::default());
    let board = Board {
        shared: shared.clone(),
        open: [false, true, false, true],
    };
    let loop_domain = domain.domain().clone();
    let vacuum = std::thread::spawn(move || {
        let context = Context::new(&loop_domain, "vacuum").expect("vacuum context");
        let arm_node = ArmNodeConfig::default();
        let node = VacuumNode::new(
            VacuumNodeConfig::default(),
            Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
                pick_reachable(arm, *centre, radius_m, &arm_node)
            }),
        )
        .expect("node");
        let args = VacuumArgs {
            policy: PolicyArg::V2024,
            arms: 2,
            device: VacuumDevice::Sim,
            port: None,
            config: None,
            without_operator: false,
        };
        control_loop(
            &context,
            board,
            node,
            &VacuumProcessConfig::default(),
            &args,
        )
    });

    let context = Context::new(&domain, "test").expect("test context");
    let mut estop_out = context.publisher(EMERGENCY_STOP).expect("estop publisher");
    let state_in = context.subscriber(VACUUM_STATE).expect("state subscriber");
    wait_for("the first vacuum state", || {
        state_in.receive_latest().expect("receive").is_some()
    });

    // Reads fail: nothing is closed for that alone.
    shared.fail_reads.store(true, Ordering::SeqCst);
    let failing_ns = MonotonicClock::read_ns();
    wait_for("ten periods of failed reads", || {
        periods_after(&shared, failing_ns).len() >= 10
    });
    let periods = periods_after(&shared, failing_ns);
    assert!(
        periods[1..].iter().flatten().all(|c| c.0 == Call::Read),
        "{periods:?}"
    );

    // The stop during the burst, the board refusing commands too: close_all is sent every
    // period from the first one after the stop.
    shared.fail_writes.store(true, Ordering::SeqCst);
    let engaged_ns = MonotonicClock::read_ns();
    let mut estop = EmergencyStop {
        engaged: 1,
        ..EmergencyStop::default()
    };
    estop_out.publish(&estop).expect("engaged");
    wait_for("ten periods after the stop", || {
        periods_after(&shared, engaged_ns).len() >= 10
    });
    let periods = periods_after(&shared, engaged_ns);
    // A tick closes before it reads: each period's close_all ends the list of the one before.
    assert!(
        periods.iter().all(|p| p.contains(&(Call::CloseAll, false))),
        "{periods:?}"
    );

    // The board takes commands again: closed once, then left alone while the stop holds.
    shared.fail_writes.store(false, Ordering::SeqCst);
    let accepted_ns = MonotonicClock::read_ns();
    wait_for("ten periods after the board recovered", || {
        periods_after(&shared, accepted_ns).len() >= 10
    });
    let closes: Vec<bool> = periods_after(&shared, accepted_ns)
        .into_iter()
        .flatten()
        .filter(|c| c.0 == Call::CloseAll)
        .map(|c| c.1)
        .collect();
    assert!(closes.iter().filter(|&&ok| ok).count() <= 1, "{closes:?}");
    assert!(
        shared
            .calls
            .lock()
            .unwrap()
            .iter()
            .any(|&(at, call, ok)| at > accepted_ns && call == Call::CloseAll && ok),
        "the close was never taken"
    );

    // A streak of failed reads ends the loop (2000 in a row: 10 s), the valves closed.
    estop.engaged = 0;
    estop_out.publish(&estop).expect("released");
    let result = vacuum.join().expect("vacuum thread");
    assert!(
        matches!(
            result,
            Err(VacuumProcessError::Run(RunError::Device { ref node, .. })) if node == "vacuum"
        ),
        "{result:?}"
    );
    // The last valve command the board took closed every valve (nothing was written while the
    // reads failed, so the close of the stop still stands).
    let calls = shared.calls.lock().unwrap();
    let last_taken = calls.iter().rev().find(|c| c.1 != Call::Read && c.2);
    assert_eq!(last_taken.map(|c| c.1), Some(Call::CloseAll), "{calls:?}");
}
