//! The safety monitor in the loop, with the real processes over real shared memory: a faulty
//! vacuum supervisor (the test-only fixture `harvest-fixture open-both-valves`, in place of
//! `harvest vacuum`) opens both arms' source valves with neither cup sealed; `harvest monitor
//! --on-violation stop` finds the violation and publishes it on `safety/violation`; the
//! executive, the one writer of `safety/emergency_stop`, engages the protective stop and both
//! arms brake. The stop stays engaged (only an operator releases it), the recorder keeps the
//! violation, and the summary of `harvest up` names it. The delays from the violation to the
//! engaged stop and to both arms holding are printed (measured, not asserted).

mod common;

use common::*;
use harvest_ipc::catalogue::{ARM_STATE, EMERGENCY_STOP, SAFETY_VIOLATION};
use harvest_ipc::payloads::{ArmPhase, ViolationRule};
use harvest_ipc::{Context, Domain};
use std::time::{Duration, Instant};

/// The stack without `vacuum`: the fixture publishes `vacuum/state` instead.
fn launch(fixture: &str, recordings: &str) -> String {
    format!(
        r#"
[stack]
hang_timeout_ms = 5000
shutdown_grace_ms = 3000
startup_grace_ms = 15000

[[process]]
name = "sim"
command = "sim"
args = ["--seed", "1", "--camera-rate-hz", "2"]
restart = "on-failure"

[[process]]
name = "arm1"
command = "arm"
args = ["--id", "1"]
restart = "on-failure"

[[process]]
name = "arm2"
command = "arm"
args = ["--id", "2"]
restart = "on-failure"

[[process]]
name = "recorder"
command = "recorder"
args = ["--output-dir", "{recordings}"]
restart = "on-failure"

[[process]]
name = "monitor"
command = "monitor"
args = ["--on-violation", "stop"]
restart = "on-failure"

[[process]]
name = "executive"
command = "executive"
args = ["--initial-mode", "harvesting", "--platform", "sim"]
restart = "on-failure"

[[process]]
name = "vacuum"
executable = "{fixture}"
args = ["open-both-valves"]
restart = "never"
"#
    )
}

/// How long a loaded 2-core machine may take from `harvest up` to the stop.
const LIMIT: Duration = Duration::from_secs(60);

#[test]
fn a_forbidden_valve_state_makes_the_monitor_stop_the_robot_and_the_summary_names_it() {
    let _one = one_stack_at_a_time();
    let dir = TempDir::new("monitor-stop");
    let recordings = dir.0.join("recordings");
    let launch_file = dir.write(
        "launch.toml",
        &launch(&fixture_executable(), &recordings.display().to_string()),
    );
    let domain_name = unique_domain("monstop");
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "test-observer").expect("context");
    let violations = context
        .subscriber_with_buffer(SAFETY_VIOLATION, 256)
        .expect("violation subscriber");
    let stops = context
        .subscriber_with_buffer(EMERGENCY_STOP, 64)
        .expect("e-stop subscriber");
    let states = ARM_STATE.map(|channel| {
        context
            .subscriber_with_buffer(channel, 256)
            .expect("state subscriber")
    });

    let running = Drained::spawn(
        &domain_name,
        &[
            "up",
            "--launch",
            launch_file.to_str().expect("utf-8 path"),
            "--duration",
            "120s",
        ],
    );

    // The first violation asking for the stop, then the engaged stop, then both arms holding.
    let deadline = Instant::now() + LIMIT;
    let mut violation: Option<(u64, String)> = None;
    let mut stop_ns: Option<u64> = None;
    let mut stop_reason = String::new();
    let mut holding_ns: [Option<u64>; 2] = [None; 2];
    while Instant::now() < deadline && holding_ns.iter().any(Option::is_none) {
        while let Some(message) = violations.receive().expect("receive violation") {
            if violation.is_none() && message.requests_stop() {
                assert_ne!(
                    message.rule.get(),
                    Ok(ViolationRule::ReactionMeasurement),
                    "a stop request without a violation"
                );
                violation = Some((
                    message.header.capture_ns,
                    message.description.as_str().to_owned(),
                ));
            }
        }
        while let Some(message) = stops.receive().expect("receive e-stop") {
            if let Some((violation_ns, _)) = violation
                && stop_ns.is_none()
                && message.engaged == 1
                && message.header.capture_ns >= violation_ns
            {
                stop_ns = Some(message.header.capture_ns);
                stop_reason = message.reason.as_str().to_owned();
            }
        }
        for (arm, subscriber) in states.iter().enumerate() {
            while let Some(state) = subscriber.receive().expect("receive arm state") {
                if let Some(stop_ns) = stop_ns
                    && holding_ns[arm].is_none()
                    && state.phase == ArmPhase::Stopped
                    && state.header.capture_ns >= stop_ns
                {
                    holding_ns[arm] = Some(state.header.capture_ns);
                }
            }
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let (violation_ns, description) = violation.clone().unwrap_or_default();
    let measured = |to: Option<u64>| {
        to.map_or_else(
            || "not seen".to_owned(),
            |to| format!("{:.1} ms", to.saturating_sub(violation_ns) as f64 * 1e-6),
        )
    };
    let holding = holding_ns[0].zip(holding_ns[1]).map(|(a, b)| a.max(b));
    eprintln!(
        "MEASURED monitor violation -> protective stop engaged: {}; -> both arms holding: {} \
         (violation: {description})",
        measured(stop_ns),
        measured(holding)
    );

    let (status, stdout, stderr) = running.interrupt_and_wait(Duration::from_secs(60));
    assert!(violation.is_some(), "no violation published:\n{stderr}");
    assert!(stop_ns.is_some(), "the stop was not engaged:\n{stderr}");
    assert!(
        stop_reason.contains("safety monitor"),
        "the stop names another cause: {stop_reason}"
    );
    assert!(
        holding.is_some(),
        "the arms did not report themselves stopped:\n{stderr}"
    );
    assert!(status.success(), "harvest up failed:\n{stderr}");
    // Nothing released the stop: the latest state of the e-stop is still engaged.
    let mut last_engaged = Some(true);
    while let Some(message) = stops.receive().expect("receive e-stop") {
        last_engaged = Some(message.engaged == 1);
    }
    assert_eq!(last_engaged, Some(true), "the stop was released");

    // The summary of `harvest up` names the violation.
    assert!(
        stdout.contains("VIOLATION ") && stdout.contains("protective stop requested"),
        "summary without the violation:\n{stdout}"
    );
    assert!(
        stdout.contains("BothOpenUnsealed") || stdout.contains("OpenedBesideUnsealed"),
        "summary names another rule:\n{stdout}"
    );

    // The recorder kept it.
    let files = mcap_files(&recordings);
    let mut recorded = 0;
    for file in &files {
        let (status, out, err) = run_harvest(
            &domain_name,
            &[
                "rec",
                "cat",
                file.to_str().expect("utf-8 path"),
                "--topic",
                "safety/violation",
            ],
            Duration::from_secs(60),
        );
        assert!(status.success(), "rec cat {}: {err}", file.display());
        recorded += out
            .lines()
            .filter(|l| l.contains("safety/violation"))
            .count();
    }
    assert!(
        recorded >= 1,
        "no safety/violation message in the recordings {files:?}"
    );
    drop(violations);
    drop(stops);
    drop(states);
    drop(context);
    assert_eq!(
        leftover_files(&domain_name),
        "",
        "iceoryx2 resources left behind"
    );
}
