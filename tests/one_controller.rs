//! One controller per robot, with the real processes over real shared memory: a second
//! `harvest up` in a domain where a stack runs is refused naming the running supervisor, a stray
//! `harvest arm --id 1` cannot become a second writer of arm 1's channels, a supervisor killed
//! with SIGKILL leaves no lock behind, and an arm killed with SIGKILL is restarted and publishes
//! again (its stale ports are cleaned, so the single-writer channels take the new process).

mod common;

use common::*;
use harvest_ipc::catalogue::{ARM_STATE, PROCESS_HEALTH};
use harvest_ipc::payloads::{ArmState, ProcessHealth};
use harvest_ipc::{Context, Domain, Payload, Subscriber};
use std::time::{Duration, Instant};

/// The simulated robot (camera at a low rate: these tests are about processes, not frames) and
/// both arms, restarted when they fail.
const LAUNCH: &str = r#"
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
backoff_initial_ms = 100

[[process]]
name = "arm2"
command = "arm"
args = ["--id", "2"]
restart = "on-failure"
"#;

/// How long a stack may take to bring arm 1 up on a loaded 2-core machine.
const START_LIMIT: Duration = Duration::from_secs(40);

/// A stack of [`LAUNCH`] in its own domain, and the test's view of its channels.
struct Stack {
    domain: common::TestDomain,
    _dir: TempDir,
    launch: String,
}

impl Stack {
    fn new(tag: &str) -> Self {
        let dir = TempDir::new(tag);
        let launch = dir.write("launch.toml", LAUNCH).display().to_string();
        Self {
            domain: unique_domain(tag),
            _dir: dir,
            launch,
        }
    }

    fn up(&self) -> Drained {
        Drained::spawn(
            &self.domain,
            &["up", "--launch", &self.launch, "--duration", "120s"],
        )
    }

    fn observer(&self) -> Observer {
        let domain = Domain::new(&self.domain).expect("domain");
        let context = Context::new(&domain, "test-observer").expect("context");
        let health = context
            .subscriber_with_buffer(PROCESS_HEALTH, 256)
            .expect("health subscriber");
        let arm1_state = context.subscriber(ARM_STATE[0]).expect("state subscriber");
        Observer {
            health,
            arm1_state,
            _context: context,
        }
    }
}

/// Heartbeats and arm 1's state, as read from the domain.
struct Observer {
    health: Subscriber<ProcessHealth>,
    arm1_state: Subscriber<ArmState>,
    _context: Context,
}

impl Observer {
    /// Waits for a heartbeat of `arm1` from a process other than `not_pid`, then for arm 1
    /// states published after it; returns that process's pid.
    fn wait_for_arm1(&self, not_pid: Option<u32>, limit: Duration) -> Result<u32, String> {
        let deadline = Instant::now() + limit;
        let mut pid = None;
        let mut last_state_seq = None;
        let mut states_after_beat = 0;
        while Instant::now() < deadline {
            while let Ok(Some(beat)) = self.health.receive() {
                if beat.process_name.as_str() == "arm1" && Some(beat.pid) != not_pid {
                    pid = Some(beat.pid);
                }
            }
            while let Ok(Some(state)) = self.arm1_state.receive() {
                last_state_seq = Some(state.header().msg_seq);
                if pid.is_some() {
                    states_after_beat += 1;
                }
            }
            if let Some(pid) = pid
                && states_after_beat >= 10
            {
                return Ok(pid);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        Err(format!(
            "arm1 (other than pid {not_pid:?}) not publishing after {limit:?}: heartbeat pid \
{pid:?}, last state msg_seq {last_state_seq:?}, states after the heartbeat {states_after_beat}"
        ))
    }

    /// The `msg_seq` of the newest arm 1 state, waiting up to `limit` for one.
    fn latest_arm1_seq(&self, limit: Duration) -> Option<u64> {
        let deadline = Instant::now() + limit;
        let mut latest = None;
        while Instant::now() < deadline {
            while let Ok(Some(state)) = self.arm1_state.receive() {
                latest = Some(state.header().msg_seq);
            }
            if latest.is_some() {
                return latest;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        latest
    }

    /// Checks that arm 1 is still the process `arm1` (`replaced` says what a different pid
    /// would mean) and that it goes on publishing its state.
    fn assert_arm1_still_publishing(&self, arm1: u32, replaced: &str) {
        let before = self
            .latest_arm1_seq(Duration::from_secs(5))
            .expect("arm 1 state");
        let still = self
            .wait_for_arm1(None, Duration::from_secs(10))
            .unwrap_or_else(|error| panic!("{error}"));
        assert_eq!(still, arm1, "{replaced}");
        let after = self
            .latest_arm1_seq(Duration::from_secs(5))
            .expect("arm 1 state");
        assert!(
            after > before,
            "arm 1 stopped publishing: {before} -> {after}"
        );
    }
}

/// Stops `stack` with SIGINT and checks it ended cleanly with no restart of arm 1 beyond
/// `arm1_restarts` and nothing left in shared memory.
fn stop_cleanly(stack: &Stack, running: Drained, arm1_restarts: u32) -> String {
    let (status, _, stderr) = running.interrupt_and_wait(Duration::from_secs(30));
    assert!(status.success(), "the stack did not end cleanly:\n{stderr}");
    assert_eq!(
        summary_restarts(&stderr, "arm1"),
        Some(arm1_restarts),
        "{stderr}"
    );
    assert_eq!(
        leftover_files(&stack.domain),
        "",
        "iceoryx2 resources left behind"
    );
    stderr
}

#[test]
fn a_second_harvest_up_in_the_same_domain_is_refused_naming_the_running_supervisor() {
    let _one = one_stack_at_a_time();
    let stack = Stack::new("twice");
    let first = stack.up();
    let observer = stack.observer();
    let arm1 = observer
        .wait_for_arm1(None, START_LIMIT)
        .unwrap_or_else(|error| panic!("{error}"));

    let (status, _, stderr) = run_harvest(
        &stack.domain,
        &["up", "--launch", &stack.launch, "--duration", "30s"],
        Duration::from_secs(60),
    );
    assert!(!status.success(), "the second stack started:\n{stderr}");
    let expected = format!(
        "a stack is already running in domain {:?}: `harvest up` with pid {}",
        &*stack.domain,
        first.pid()
    );
    assert!(stderr.contains(&expected), "{expected:?} not in:\n{stderr}");
    assert!(
        !stderr.contains("started process="),
        "the refused supervisor started processes:\n{stderr}"
    );

    // The first stack is unaffected: the same arm 1 process goes on publishing.
    observer.assert_arm1_still_publishing(arm1, "arm 1 was restarted");
    drop(observer);
    stop_cleanly(&stack, first, 0);
}

#[test]
fn a_stray_arm_process_cannot_become_a_second_writer() {
    let _one = one_stack_at_a_time();
    let stack = Stack::new("stray");
    let running = stack.up();
    let observer = stack.observer();
    let arm1 = observer
        .wait_for_arm1(None, START_LIMIT)
        .unwrap_or_else(|error| panic!("{error}"));

    let (status, _, stderr) = run_harvest(
        &stack.domain,
        &["arm", "--id", "1"],
        Duration::from_secs(30),
    );
    assert!(!status.success(), "the stray arm ran:\n{stderr}");
    // The first channel it would write is its servos' set-points; the message names it, the
    // limit, and the stack that writes it.
    for needle in [
        "channel \"hw/arm1/servo\" has no room for another publisher",
        "a channel with one writer accepts no second publisher",
        &format!("`harvest up` pid {}", running.pid()),
    ] {
        assert!(stderr.contains(needle), "{needle:?} not in:\n{stderr}");
    }

    // The stack's arm 1 keeps running and publishing.
    observer.assert_arm1_still_publishing(arm1, "the stack's arm 1 was replaced");
    drop(observer);
    stop_cleanly(&stack, running, 0);
}

#[test]
fn a_killed_supervisor_leaves_no_lock_and_the_next_stack_starts() {
    let _one = one_stack_at_a_time();
    let stack = Stack::new("killsup");
    let first = stack.up();
    {
        let observer = stack.observer();
        observer
            .wait_for_arm1(None, START_LIMIT)
            .unwrap_or_else(|error| panic!("{error}"));
    }
    let old_supervisor = first.pid();
    let old_processes = children_of(old_supervisor);
    assert_eq!(old_processes.len(), 3, "sim, arm1, arm2: {old_processes:?}");
    let (status, _, _) = first.kill9_and_wait();
    assert!(!status.success());

    // At once: the new supervisor waits for the old stack's processes (they got SIGTERM when
    // their parent died), then starts.
    let second = stack.up();
    let observer = stack.observer();
    let arm1 = observer.wait_for_arm1(None, START_LIMIT);
    let gone: Vec<u32> = old_processes
        .iter()
        .copied()
        .filter(|pid| !process_running(*pid))
        .collect();
    drop(observer);
    let stderr = stop_cleanly(&stack, second, 0);
    let arm1 = arm1.unwrap_or_else(|error| panic!("{error}\n{stderr}"));
    assert!(
        !old_processes.contains(&arm1),
        "arm 1 of the killed stack still publishes"
    );
    assert_eq!(
        gone, old_processes,
        "processes of the killed stack still run"
    );
    assert!(!stderr.contains("already running"), "{stderr}");
}

#[test]
fn a_killed_arm_is_restarted_and_publishes_again() {
    let _one = one_stack_at_a_time();
    let stack = Stack::new("killarm");
    let running = stack.up();
    let observer = stack.observer();
    let first_arm1 = observer
        .wait_for_arm1(None, START_LIMIT)
        .unwrap_or_else(|error| panic!("{error}"));
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(first_arm1 as i32),
        nix::sys::signal::Signal::SIGKILL,
    )
    .expect("kill arm 1");

    let second_arm1 = observer.wait_for_arm1(Some(first_arm1), START_LIMIT);
    drop(observer);
    let stderr = stop_cleanly(&stack, running, 1);
    let second_arm1 = second_arm1.unwrap_or_else(|error| panic!("{error}\n{stderr}"));
    assert_ne!(second_arm1, first_arm1);
}
