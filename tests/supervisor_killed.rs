//! The supervisor itself killed with SIGKILL (power cut of the process, OOM killer, `kill -9`):
//! its children stop on their own (parent-death signal), its iceoryx2 node stays behind, and
//! the next `harvest up` in the domain removes those stale resources, runs, and leaves nothing.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup is a failed test

mod common;

use common::*;
use harvest_ipc::catalogue::PROCESS_HEALTH;
use harvest_ipc::{Context, Domain};
use std::collections::BTreeSet;
use std::io::Read;
use std::path::Path;
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

#[test]
fn after_the_supervisor_is_killed_the_next_start_cleans_up_and_runs() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("killsv");
    let work = TempDir::new("killsv");
    let launch_file = work.write("launch.toml", &launch(&work.0.join("recordings")));
    let launch_path = launch_file.to_str().expect("utf-8 path");

    // First run: wait until every process sends heartbeats, then SIGKILL the supervisor.
    let mut first = spawn_harvest(&domain, &["up", "--launch", launch_path]);
    let mut first_stderr = first.stderr.take().expect("stderr piped");
    let stderr_reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = first_stderr.read_to_string(&mut text);
        text
    });
    let stack_children = {
        let context =
            Context::new(&Domain::new(&domain).expect("domain"), "test-health").expect("context");
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
            assert!(
                Instant::now() < deadline,
                "watchdog: heartbeats only from {seen:?} within 90 s"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        children(first.id())
    };
    assert_eq!(stack_children.len(), 3, "{stack_children:?}");
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(first.id() as i32),
        nix::sys::signal::Signal::SIGKILL,
    )
    .expect("SIGKILL the supervisor");
    let _ = first.wait().expect("reap the killed supervisor");
    let first_stderr = stderr_reader.join().unwrap_or_default();
    // The children got their parent-death signal and stop by themselves.
    let deadline = Instant::now() + Duration::from_secs(30);
    while stack_children.iter().any(|pid| is_running(*pid)) {
        assert!(
            Instant::now() < deadline,
            "watchdog: children {stack_children:?} outlived the killed supervisor:\n{first_stderr}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    // What the killed supervisor left: its node and ports.
    let stale = list_leftover_files(&domain);
    assert!(
        !stale.is_empty(),
        "the killed supervisor left nothing to clean up (test premise)"
    );

    // Second run in the same domain: cleans up, runs, stops cleanly.
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
