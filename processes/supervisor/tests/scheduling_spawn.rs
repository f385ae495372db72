//! A real child started with scheduling settings: what the supervisor reports as granted is what
//! the kernel shows for the running process (`/proc/<pid>/stat`, `/proc/<pid>/status`), a
//! refused real-time priority still starts the process, and the memory lock is handed to the
//! process through its environment.

use std::os::fd::AsRawFd as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use harvest_supervisor::child;
use harvest_supervisor::launch::{ProcessSpec, RestartPolicy};
use harvest_supervisor::scheduling::{CallOutcome, Scheduling};

fn sleeper(scheduling: Scheduling) -> ProcessSpec {
    ProcessSpec {
        name: "sleeper".to_owned(),
        command: "/bin/sleep".to_owned(),
        executable: Some(PathBuf::from("/bin/sleep")),
        args: vec!["5".to_owned()],
        restart: RestartPolicy::Never,
        max_restarts: 0,
        restart_window: Duration::from_secs(1),
        backoff_initial: Duration::from_millis(1),
        backoff_max: Duration::from_millis(1),
        scheduling,
        critical: true,
    }
}

/// `(policy, rt_priority, nice)` from `/proc/<pid>/stat` (fields 41, 40 and 19).
fn kernel_scheduling(pid: u32) -> (u32, u32, i32) {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("stat");
    // Fields after the command name (which is in parentheses and may hold spaces).
    let after = &stat[stat.rfind(')').expect("comm") + 2..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    // `after` starts at field 3 (state).
    let field = |n: usize| fields[n - 3];
    (
        field(41).parse().expect("policy"),
        field(40).parse().expect("rt_priority"),
        field(19).parse().expect("nice"),
    )
}

fn cpus_allowed(pid: u32) -> String {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    status
        .lines()
        .find_map(|line| line.strip_prefix("Cpus_allowed_list:"))
        .expect("Cpus_allowed_list")
        .trim()
        .to_owned()
}

#[test]
fn granted_settings_are_what_the_kernel_applied() {
    let asked = Scheduling {
        realtime_priority: Some(1),
        cpus: vec![0],
        nice: Some(5),
        lock_memory: true,
    };
    let lock_file = std::fs::File::open("/dev/null").expect("a descriptor to pass");
    let domain = harvest_ipc::ScratchDomain::new("schedspawn");
    let (mut process, outcome) = child::spawn(
        Path::new("/unused"),
        &sleeper(asked.clone()),
        &domain,
        lock_file.as_raw_fd(),
        "test-token",
    )
    .expect("spawn");
    let pid = process.id();
    let (policy, rt_priority, nice) = kernel_scheduling(pid);
    let environ = std::fs::read(format!("/proc/{pid}/environ")).expect("environ");
    let cpus = cpus_allowed(pid);
    process.kill().expect("kill");
    process.wait().expect("wait");

    assert_eq!(outcome.asked, asked);
    // A positive nice needs no privilege.
    assert_eq!(outcome.nice, CallOutcome::Applied);
    assert_eq!(nice, 5);
    assert_eq!(outcome.affinity, CallOutcome::Applied);
    assert_eq!(cpus, "0");
    // SCHED_FIFO is 1, SCHED_OTHER 0: granted or refused, the report says what the kernel did,
    // and a refused process runs anyway.
    match outcome.realtime {
        CallOutcome::Applied => assert_eq!((policy, rt_priority), (1, 1)),
        CallOutcome::Refused(errno) => {
            assert_eq!(errno, nix::errno::Errno::EPERM);
            assert_eq!((policy, rt_priority), (0, 0));
            assert!(outcome.refusals()[0].contains("runs with normal scheduling"));
        }
        other => panic!("no report from the child: {other:?}"),
    }
    let marker = format!("{}=1", harvest_ipc::memory_lock::LOCK_MEMORY_ENV);
    assert!(
        environ
            .split(|&byte| byte == 0)
            .any(|entry| entry == marker.as_bytes()),
        "{marker} not in the child's environment"
    );
}

#[test]
fn a_process_without_settings_is_started_as_before() {
    let lock_file = std::fs::File::open("/dev/null").expect("a descriptor to pass");
    let domain = harvest_ipc::ScratchDomain::new("schedspawn");
    let (mut process, outcome) = child::spawn(
        Path::new("/unused"),
        &sleeper(Scheduling::default()),
        &domain,
        lock_file.as_raw_fd(),
        "test-token",
    )
    .expect("spawn");
    let (policy, _, _) = kernel_scheduling(process.id());
    process.kill().expect("kill");
    process.wait().expect("wait");
    assert_eq!(outcome.label(), "");
    assert_eq!(policy, 0);
}
