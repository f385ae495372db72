//! The harvest end to end with the real processes over real shared memory: `harvest up` with
//! the simulated robot, camera, perception, both arms and the vacuum supervisor picks a small
//! orchard, prints per-apple events and the summary, and exits clean; bad targets published on
//! an arm's target channel are refused with a reason on `harvest/events` and the arm holds; a
//! non-critical process that fails for good is reported and does not end the harvest.

mod common;

use common::*;
use harvest_ipc::catalogue::{
    ARM_STATE, ARM_TARGET, HARVEST_EVENTS, PROCESS_HEALTH, SIM_GROUND_TRUTH,
};
use harvest_ipc::payloads::{
    ArmPhase, ArmTarget, HarvestCause, HarvestEvent, HarvestEventKind, ProcessRunState,
    TrueAppleState,
};
use harvest_ipc::{Context, Domain, MonotonicClock};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[test]
fn harvest_up_picks_a_small_orchard_and_summarizes_it() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("harvest");
    let dir = TempDir::new("harvest");
    let scenario = dir.write("few.toml", &ideal_orchard(4, 0.0));
    let launch_file = dir.write(
        "launch.toml",
        &picking_launch(&scenario.display().to_string(), true, ""),
    );

    // Ground truth, read while the stack runs: the apples the simulator put on the module.
    let stop = Arc::new(AtomicBool::new(false));
    let truth_harvested = Arc::new(Mutex::new(None::<usize>));
    let truth_thread = {
        let (stop, truth_harvested, domain) =
            (stop.clone(), truth_harvested.clone(), domain.to_string());
        std::thread::spawn(move || {
            let domain = Domain::new(&domain).expect("domain");
            let context = Context::new(&domain, "test-truth").expect("context");
            let truth = context.subscriber(SIM_GROUND_TRUTH).expect("subscriber");
            while !stop.load(Ordering::SeqCst) {
                if let Ok(Some(sample)) = truth.receive_latest() {
                    let harvested = sample
                        .apples
                        .iter()
                        .filter(|a| a.state == TrueAppleState::Harvested)
                        .count();
                    *truth_harvested.lock().expect("lock") = Some(harvested);
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        })
    };

    let (status, stdout, stderr) = run_harvest(
        &domain,
        &[
            "up",
            "--launch",
            &launch_file.display().to_string(),
            "--until-harvested",
            "--duration",
            "75s",
        ],
        Duration::from_secs(110),
    );
    stop.store(true, Ordering::SeqCst);
    truth_thread.join().expect("truth thread");

    assert!(status.success(), "harvest up failed:\n{stdout}\n{stderr}");
    assert!(
        stderr.contains("harvest up ended: harvest complete"),
        "the harvest did not complete:\n{stdout}\n{stderr}"
    );
    let attempted = summary_count(&stdout, "attempted").expect("summary line");
    let harvested = summary_count(&stdout, "harvested").expect("summary line");
    assert!(harvested > 0, "nothing harvested:\n{stdout}");
    // Attempts may exceed the apples: perception can see an apple in a retracting cup as a new
    // one, and the arm then finds nothing there.
    assert!(harvested <= attempted, "{stdout}");
    // Per-apple lines: assignment, phases and the result of each harvested apple.
    for needle in [
        "assigned at",
        "phase Approach",
        "phase AttachDetach",
        "phase Retract",
    ] {
        assert!(stdout.contains(needle), "no {needle:?} line:\n{stdout}");
    }
    let results = stdout.lines().filter(|l| l.contains("HARVESTED")).count();
    assert_eq!(results as u32, harvested, "{stdout}");
    // The arms' account agrees with the simulator's ground truth.
    let truth = *truth_harvested.lock().expect("lock");
    assert_eq!(
        truth,
        Some(harvested as usize),
        "ground truth disagrees with the summary:\n{stdout}"
    );
    assert_eq!(
        leftover_files(&domain),
        "",
        "iceoryx2 resources left behind"
    );
}

/// A launch file with a non-critical process that always fails (the fault-injection fixture,
/// `critical = false`): it fails for good early, the supervisor reports it (the summary, its
/// state on `system/health`) and the harvest goes on to completion; `harvest up` exits 0.
#[test]
fn a_non_critical_process_failing_for_good_does_not_end_the_harvest() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("noncrit");
    let dir = TempDir::new("noncrit");
    let scenario = dir.write("few.toml", &ideal_orchard(2, 0.0));
    let mut text = picking_launch(&scenario.display().to_string(), true, "");
    text.push_str(&format!(
        r#"
[[process]]
name = "crasher"
executable = "{fixture}"
args = ["always-crash"]
restart = "on-failure"
max_restarts = 2
backoff_initial_ms = 50
backoff_max_ms = 100
critical = false
"#,
        fixture = fixture_executable()
    ));
    let launch_file = dir.write("launch.toml", &text);

    // The supervisor's word on the failed process, on system/health, while the stack runs.
    let stop = Arc::new(AtomicBool::new(false));
    let failed_beat = Arc::new(Mutex::new(None::<String>));
    let health_thread = {
        let (stop, failed_beat, domain) = (stop.clone(), failed_beat.clone(), domain.to_string());
        std::thread::spawn(move || {
            let domain = Domain::new(&domain).expect("domain");
            let context = Context::new(&domain, "test-health").expect("context");
            let health = context
                .subscriber_with_buffer(PROCESS_HEALTH, 256)
                .expect("subscriber");
            while !stop.load(Ordering::SeqCst) {
                while let Ok(Some(beat)) = health.receive() {
                    if beat.process_name.as_str() == "crasher"
                        && beat.run_state.get() == Ok(ProcessRunState::Failed)
                    {
                        *failed_beat.lock().expect("lock") = Some(beat.detail.as_str().to_owned());
                    }
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        })
    };
    let (status, stdout, stderr) = run_harvest(
        &domain,
        &[
            "up",
            "--launch",
            &launch_file.display().to_string(),
            "--until-harvested",
            "--duration",
            "75s",
        ],
        Duration::from_secs(110),
    );
    stop.store(true, Ordering::SeqCst);
    health_thread.join().expect("health thread");

    assert!(status.success(), "harvest up failed:\n{stdout}\n{stderr}");
    assert!(
        stderr.contains("harvest up ended: harvest complete"),
        "the harvest did not complete:\n{stdout}\n{stderr}"
    );
    assert!(
        summary_count(&stdout, "harvested").is_some_and(|n| n > 0),
        "nothing harvested:\n{stdout}"
    );
    assert!(
        stderr.contains(
            "not critical, the stack went on: process \"crasher\" failed for good: exit code 3"
        ),
        "{stderr}"
    );
    let line = stderr[stderr.find("harvest up ended").expect("summary")..]
        .lines()
        .find(|l| l.trim_start().starts_with("crasher"))
        .expect("crasher's summary line");
    assert!(line.contains("FAILED:noncritical"), "{line}");
    assert_eq!(summary_restarts(&stderr, "crasher"), Some(2), "{stderr}");
    assert!(!stderr.contains("\nfailure:"), "{stderr}");
    assert_eq!(
        failed_beat.lock().expect("lock").as_deref(),
        Some("failed for good, restarts"),
        "no failed state on system/health"
    );
    assert_eq!(leftover_files(&domain), "");
}

/// Waits until `arm1/state` shows an idle arm with finite joints and `arm2/state` is flowing;
/// returns arm 1's joints, or the last states seen.
fn wait_for_idle_arm(context: &Context, limit: Duration) -> Result<[f64; 4], String> {
    let states = [
        context.subscriber(ARM_STATE[0]).expect("subscriber"),
        context.subscriber(ARM_STATE[1]).expect("subscriber"),
    ];
    let deadline = Instant::now() + limit;
    let mut seen = [None, None];
    while Instant::now() < deadline {
        for (i, subscriber) in states.iter().enumerate() {
            if let Ok(Some(state)) = subscriber.receive_latest() {
                seen[i] = Some(*state);
            }
        }
        if let [Some(one), Some(_)] = seen
            && one.phase == ArmPhase::Idle
            && one.joint_position.iter().all(|q| q.is_finite())
        {
            return Ok(one.joint_position);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Err(format!(
        "arms not running after {limit:?}: last states {seen:?}"
    ))
}

#[test]
fn bad_targets_are_rejected_with_a_reason_and_the_arm_holds() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("badtarget");
    let dir = TempDir::new("badtarget");
    let scenario = dir.write("few.toml", &ideal_orchard(2, 0.0));
    let launch_file = dir.write(
        "launch.toml",
        &picking_launch(&scenario.display().to_string(), false, ""),
    );
    let child = Drained::spawn(
        &domain,
        &[
            "up",
            "--launch",
            &launch_file.display().to_string(),
            "--duration",
            "60s",
        ],
    );

    let outcome = {
        let ipc_domain = Domain::new(&domain).expect("domain");
        let context = Context::new(&ipc_domain, "test-bad-targets").expect("context");
        let events = context
            .subscriber_with_buffer(HARVEST_EVENTS, 256)
            .expect("subscriber");
        let mut targets = context.publisher(ARM_TARGET[0]).expect("publisher");
        let before = wait_for_idle_arm(&context, Duration::from_secs(40));
        let Ok(before) = before else {
            drop(context);
            let (_, stdout, stderr) = child.interrupt_and_wait(Duration::from_secs(30));
            let _ = leftover_files(&domain);
            panic!("{before:?}\n{stdout}\n{stderr}");
        };

        let now_ns = MonotonicClock::read_ns();
        let target = |apple_id: u32, position: [f64; 3], source_capture_ns: u64| ArmTarget {
            arm_id: 1,
            apple_id,
            position_in_robot_m: position,
            radius_m: 0.04,
            source_capture_ns,
            ..ArmTarget::default()
        };
        let cases = [
            (
                901,
                target(901, [f64::NAN, 0.1, 0.3], now_ns),
                HarvestCause::NonFinite,
            ),
            (
                902,
                target(902, [3.0, 0.2, 0.4], now_ns),
                HarvestCause::OutsideWorkspace,
            ),
            (
                903,
                // Seen 10 s ago: older than the 2 s the arm accepts.
                target(903, [1.25, 0.2, 0.4], now_ns.saturating_sub(10_000_000_000)),
                HarvestCause::Stale,
            ),
        ];
        let mut rejections: Vec<HarvestEvent> = Vec::new();
        for (apple_id, mut message, _) in cases {
            message.header.capture_ns = MonotonicClock::read_ns();
            targets.publish(&message).expect("publish target");
            let deadline = Instant::now() + Duration::from_secs(10);
            while Instant::now() < deadline && !rejections.iter().any(|e| e.apple_id == apple_id) {
                while let Ok(Some(event)) = events.receive() {
                    if event.kind == HarvestEventKind::TargetRejected {
                        rejections.push(*event);
                    }
                    assert_ne!(
                        event.kind,
                        HarvestEventKind::TargetAccepted,
                        "a bad target was accepted: {:?}",
                        *event
                    );
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        // Let a possible (wrong) motion show in the joints, then compare.
        std::thread::sleep(Duration::from_millis(500));
        let after = wait_for_idle_arm(&context, Duration::from_secs(5)).unwrap_or([f64::NAN; 4]);
        (
            rejections,
            before,
            after,
            cases.map(|(id, _, cause)| (id, cause)),
        )
    };

    let (status, stdout, stderr) = child.interrupt_and_wait(Duration::from_secs(30));
    let (rejections, before, after, expected) = outcome;
    assert!(status.success(), "harvest up failed:\n{stderr}");
    for (apple_id, cause) in expected {
        let event = rejections
            .iter()
            .find(|e| e.apple_id == apple_id)
            .unwrap_or_else(|| panic!("no rejection of target {apple_id}: {rejections:?}"));
        assert_eq!(event.cause, cause, "{event:?}");
        assert_eq!(event.arm_id, 1);
        assert_eq!(
            event.harvested, 0,
            "a bad target must not be retried: {event:?}"
        );
        assert!(
            event.reason.as_str().contains(&apple_id.to_string()),
            "reason does not name the target: {event:?}"
        );
    }
    // The arm held: still idle where it was (encoder noise only).
    for (j, (a, b)) in before.iter().zip(after.iter()).enumerate() {
        assert!((a - b).abs() < 1e-3, "joint {j} moved from {a} to {b}");
    }
    // `harvest up` printed the refusals.
    assert!(
        stdout.contains("target rejected (outside_workspace)"),
        "no rejection line:\n{stdout}"
    );
    assert_eq!(
        leftover_files(&domain),
        "",
        "iceoryx2 resources left behind"
    );
}
