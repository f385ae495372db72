//! The stop always wins: the arm's real control loop over real shared memory, its servos a
//! double that fails reads and writes on command. An emergency stop engaged during a burst of
//! encoder errors brakes the arm from the next tick on, and the published command and state
//! say so; a device error alone brakes too; a loop that ends on device errors leaves the arm
//! braked.

use std::time::{Duration, Instant};

use harvest_arm_process::process::{ArmProcessConfig, ArmProcessError, control_loop};
use harvest_hw::arm_servos::double::{ServoCall, ServoCallKind, ServoDouble, ServoDoubleControl};
use harvest_ipc::catalogue::{ARM_COMMAND, ARM_STATE, EMERGENCY_STOP};
use harvest_ipc::payloads::{ArmPhase, EmergencyStop};
use harvest_ipc::{Context, MonotonicClock, ScratchDomain};
use harvest_robot_model::ModeSource;
use harvest_robot_model::params::ArmId;
use harvest_runtime::RunError;

/// Longest wait for anything the loop should do within a few ticks (a watchdog, not a bound
/// on its timing).
const WATCHDOG: Duration = Duration::from_secs(20);

fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < WATCHDOG, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The calls from each encoder read made after `after_ns` up to the next read, one list per
/// period, the read first (the last, unfinished period left out). A tick that applies the
/// stop brakes before it reads, so its brake ends the previous list: each list holding a
/// brake and no set-point means the servos were braked once every period.
fn ticks_after(calls: &[ServoCall], after_ns: u64) -> Vec<Vec<ServoCall>> {
    let mut ticks: Vec<Vec<ServoCall>> = Vec::new();
    for call in calls.iter().filter(|c| c.at_ns > after_ns) {
        match call.kind {
            ServoCallKind::Read => ticks.push(vec![*call]),
            _ => {
                if let Some(tick) = ticks.last_mut() {
                    tick.push(*call);
                }
            }
        }
    }
    ticks.pop();
    ticks
}

/// True when the tick braked and sent no set-point.
fn held(tick: &[ServoCall]) -> bool {
    tick.iter().any(|c| c.kind == ServoCallKind::Hold)
        && !tick
            .iter()
            .any(|c| matches!(c.kind, ServoCallKind::Command { .. }))
}

#[test]
fn an_emergency_stop_during_encoder_errors_brakes_within_one_period() {
    let domain = ScratchDomain::new("armstop");
    let (servos, control): (ServoDouble, ServoDoubleControl) =
        ServoDouble::new([0.3, 0.0, 0.0, 0.0]);
    let arm_domain = domain.domain().clone();
    let arm = std::thread::spawn(move || {
        let context = Context::new(&arm_domain, "arm1").expect("arm context");
        let config = ArmProcessConfig::default();
        let node_config = harvest_arm::node::ArmNodeConfig::default();
        control_loop(
            &context,
            servos,
            ArmId::Arm1,
            &config,
            node_config,
            ModeSource::Executive,
        )
    });

    let context = Context::new(&domain, "test").expect("test context");
    let mut estop_out = context.publisher(EMERGENCY_STOP).expect("estop publisher");
    let state_in = context.subscriber(ARM_STATE[0]).expect("state subscriber");
    let command_in = context
        .subscriber(ARM_COMMAND[0])
        .expect("command subscriber");
    let mut estop = EmergencyStop::default();
    estop_out.publish(&estop).expect("released");

    // The arm runs on a healthy device.
    wait_for("the arm's first state", || {
        state_in.receive_latest().expect("receive").is_some()
    });

    // A burst of failing reads and writes, then the stop.
    control.fail_reads(true);
    control.fail_writes(true);
    std::thread::sleep(Duration::from_millis(30));
    let engaged_ns = MonotonicClock::read_ns();
    estop.engaged = 1;
    estop_out.publish(&estop).expect("engaged");
    wait_for("a state saying stopped", || {
        state_in
            .receive_latest()
            .expect("receive")
            .is_some_and(|s| s.phase == ArmPhase::Stopped)
    });
    wait_for("ten ticks after the stop", || {
        ticks_after(&control.calls(), engaged_ns).len() >= 10
    });
    let ticks = ticks_after(&control.calls(), engaged_ns);
    // Every tick after the stop was published braked (the first may have read the stop just
    // before it was published; it brakes for the failed read), none sent a set-point, and
    // every read failed: the stop was applied during the burst.
    assert!(ticks.iter().all(|t| held(t)), "{ticks:?}");
    assert!(ticks.iter().all(|t| !t[0].succeeded));
    let command = command_in
        .receive_latest()
        .expect("receive")
        .expect("a command");
    assert_eq!(command.hold, 1, "{:?}", *command);

    // The device recovers while the stop stays engaged: still braked every tick.
    control.fail_reads(false);
    control.fail_writes(false);
    let recovered_ns = MonotonicClock::read_ns();
    wait_for("ten ticks after the recovery", || {
        ticks_after(&control.calls(), recovered_ns).len() >= 10
    });
    let ticks = ticks_after(&control.calls(), recovered_ns);
    assert!(ticks.iter().all(|t| held(t)), "{ticks:?}");
    assert!(ticks[1..].iter().all(|t| t[0].succeeded));

    // The stop released on a healthy device: the failed reads alone still brake, from the
    // first tick that read the encoders after the failure began.
    estop.engaged = 0;
    estop_out.publish(&estop).expect("released");
    wait_for("a state saying idle again", || {
        state_in
            .receive_latest()
            .expect("receive")
            .is_some_and(|s| s.phase != ArmPhase::Stopped)
    });
    let failing_ns = MonotonicClock::read_ns();
    control.fail_reads(true);
    let result = arm.join().expect("arm thread");
    // A streak of failed reads ends the loop (the supervisor restarts the process), braked.
    assert!(
        matches!(
            result,
            Err(ArmProcessError::Run(RunError::Device { ref node, .. })) if node == "arm1"
        ),
        "{result:?}"
    );
    let calls = control.calls();
    let ticks = ticks_after(&calls, failing_ns);
    assert!(ticks.len() >= 100, "{} ticks", ticks.len());
    assert!(ticks.iter().all(|t| held(t)), "{ticks:?}");
    assert_eq!(calls.last().map(|c| c.kind), Some(ServoCallKind::Hold));
}
