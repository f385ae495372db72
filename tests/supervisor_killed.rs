//! The supervisor itself killed with SIGKILL (`kill -9`, the OOM killer): its children stop on
//! their own (parent-death signal) and the next `harvest up` in the domain runs. When the whole
//! stack is killed at once (systemd's final SIGKILL to the service, an OOM kill of the group),
//! every node stays behind: the next start removes those stale resources, runs, and leaves
//! nothing.

mod common;

use common::*;
use harvest_ipc::catalogue::PROCESS_HEALTH;
use harvest_ipc::{Context, Domain};
use std::collections::BTreeSet;
use std::io::Read;
use std::path::Path;
use std::process::Child;
use std::time::{Duration, Instant};

fn launch(recordings: &Path) -> String {
    format!(
        r#"
[stack]
hang_timeout_ms = 5000
shutdown_grace_ms = 3000
startup_grace_ms = 15000

[[process]]
name = "sim"
command = "sim"
args = ["--scenario", "default", "--seed", "1", "--camera-rate-hz", "2"]
restart = "on-failure"

[[process]]
name = "arm1"
command = "arm"
args = ["--id", "1"]
restart = "on-failure"

[[process]]
name = "recorder"
command = "recorder"
args = ["--output-dir", "{recordings}", "--max-total-size", "0"]
restart = "on-failure"
"#,
        recordings = recordings.display()
    )
}

/// Children of `pid` (from /proc).
fn children(pid: u32) -> Vec<i32> {
    std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children"))
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|child| child.parse().ok())
        .collect()
}

/// True while `pid` runs (a zombie counts as gone).
fn is_running(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|stat| {
            // The state follows the parenthesized command name.
            let after_name = stat.rsplit_once(')')?.1.trim_start().to_owned();
            after_name.chars().next()
        })
        .is_some_and(|state| state != 'Z' && state != 'X')
}

/// Starts `harvest up --launch <launch>` and waits until every process sends heartbeats;
/// returns the supervisor and its children's pids.
fn start_stack(domain: &str, launch: &str) -> (Child, Vec<i32>) {
    let mut supervisor = spawn_harvest(domain, &["up", "--launch", launch]);
    // Drain the output so a full pipe never stalls the stack.
    for pipe in [
        supervisor
            .stderr
            .take()
            .map(|pipe| Box::new(pipe) as Box<dyn Read + Send>),
        supervisor
            .stdout
            .take()
            .map(|pipe| Box::new(pipe) as Box<dyn Read + Send>),
    ]
    .into_iter()
    .flatten()
    {
        std::thread::spawn(move || {
            let mut pipe = pipe;
            let mut sink = Vec::new();
            let _ = pipe.read_to_end(&mut sink);
        });
    }
    let context =
        Context::new(&Domain::new(domain).expect("domain"), "test-health").expect("context");
    let health = context
        .subscriber_with_buffer(PROCESS_HEALTH, 256)
        .expect("health subscriber");
    let expected: BTreeSet<&str> = ["sim", "arm1", "recorder"].into();
    let mut seen = BTreeSet::new();
    let deadline = Instant::now() + Duration::from_secs(90);
    while seen != expected {
        while let Ok(Some(beat)) = health.receive() {
            if let Some(name) = expected.get(beat.process_name.as_str()) {
                seen.insert(*name);
            }
        }
        if Instant::now() > deadline {
            let _ = supervisor.kill();
            panic!("watchdog: heartbeats only from {seen:?} within 90 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let stack = children(supervisor.id());
    assert_eq!(stack.len(), 3, "{stack:?}");
    (supervisor, stack)
}

fn sigkill(pid: i32) {
    let _ = nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(pid),
        nix::sys::signal::Signal::SIGKILL,
    );
}

/// Waits (under a watchdog) until none of `pids` runs.
fn wait_gone(pids: &[i32], what: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while pids.iter().any(|pid| is_running(*pid)) {
        assert!(Instant::now() < deadline, "watchdog: {what} {pids:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn after_the_supervisor_is_killed_the_next_start_cleans_up_and_runs() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("killsv");
    let work = TempDir::new("killsv");
    let launch_file = work.write("launch.toml", &launch(&work.0.join("recordings")));
    let launch_path = launch_file.to_str().expect("utf-8 path");

    // The supervisor alone is killed: its children get their parent-death signal and stop
    // (cleaning up after the dead supervisor's node as their own nodes go).
    let (mut supervisor, stack) = start_stack(&domain, launch_path);
    sigkill(supervisor.id() as i32);
    let _ = supervisor.wait().expect("reap the killed supervisor");
    wait_gone(&stack, "children outlived the killed supervisor");

    // The next start runs; then the whole stack is killed at once: every node stays behind.
    let (mut supervisor, stack) = start_stack(&domain, launch_path);
    sigkill(supervisor.id() as i32);
    for pid in &stack {
        sigkill(*pid);
    }
    let _ = supervisor.wait().expect("reap the killed supervisor");
    wait_gone(&stack, "SIGKILLed children still running");
    let stale = list_leftover_files(&domain);
    assert!(
        !stale.is_empty(),
        "the killed stack left nothing to clean up (test premise)"
    );

    // The next start removes the stale resources, runs, and stops cleanly.
    let (status, _, stderr) = run_harvest(
        &domain,
        &["up", "--launch", launch_path, "--duration", "8s"],
        Duration::from_secs(90),
    );
    assert!(status.success(), "the restart failed:\n{stderr}");
    assert!(
        stderr.contains("removed stale iceoryx2 resources of dead nodes"),
        "no cleanup at start:\n{stderr}"
    );
    assert!(stderr.contains("--duration 8s elapsed"), "{stderr}");
    for process in ["sim", "arm1", "recorder"] {
        assert_eq!(summary_restarts(&stderr, process), Some(0), "{stderr}");
        let messages = summary_messages(&stderr, process).unwrap_or(0);
        assert!(messages > 0, "{process} did no work:\n{stderr}");
    }
    assert_eq!(
        leftover_files(&domain),
        "",
        "iceoryx2 resources left behind"
    );
}
