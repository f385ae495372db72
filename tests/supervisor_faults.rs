//! Supervisor behaviour with fault-injection fixtures: real processes, real shared memory.

mod common;

use common::*;
use std::time::Duration;

#[test]
fn crash_at_start_exhausts_restart_budget_and_exits_nonzero() {
    let dir = TempDir::new("crash");
    let launch = dir.write(
        "crash.toml",
        "[[process]]\nname = \"crasher\"\ncommand = \"fixture\"\nargs = [\"always-crash\"]\n\
         restart = \"on-failure\"\nmax_restarts = 2\nbackoff_initial_ms = 50\nbackoff_max_ms = 100\n",
    );
    let domain = unique_domain("crash");
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "up",
            "--launch",
            launch.to_str().expect("utf-8 path"),
            "--duration",
            "20s",
        ],
        Duration::from_secs(60),
    );
    assert!(!status.success(), "must fail; stderr:\n{stderr}");
    assert!(
        stderr.contains("process \"crasher\" failed for good: exit code 3"),
        "{stderr}"
    );
    assert_eq!(summary_restarts(&stderr, "crasher"), Some(2), "{stderr}");
    assert_eq!(leftover_files(&domain), "");
}

#[test]
fn hung_process_is_killed_and_restarted() {
    let dir = TempDir::new("hang");
    let launch = dir.write(
        "hang.toml",
        "[stack]\nhang_timeout_ms = 1500\nstartup_grace_ms = 1500\n\n[[process]]\nname = \"hanger\"\n\
         command = \"fixture\"\nargs = [\"hang-after-init\"]\nrestart = \"on-failure\"\n\
         max_restarts = 10\nbackoff_initial_ms = 50\n",
    );
    let domain = unique_domain("hang");
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "up",
            "--launch",
            launch.to_str().expect("utf-8 path"),
            "--duration",
            "7s",
        ],
        Duration::from_secs(60),
    );
    assert!(status.success(), "{stderr}");
    assert!(
        stderr.contains("no heartbeat: killing hung process"),
        "{stderr}"
    );
    let restarts = summary_restarts(&stderr, "hanger").expect("summary line");
    assert!(restarts >= 1, "{stderr}");
    assert_eq!(leftover_files(&domain), "");
}

#[test]
fn sigterm_ignoring_process_is_killed_after_grace() {
    let dir = TempDir::new("ignore");
    let launch = dir.write(
        "ignore.toml",
        "[stack]\nshutdown_grace_ms = 500\n\n[[process]]\nname = \"stubborn\"\ncommand = \"fixture\"\n\
         args = [\"ignore-sigterm\"]\n",
    );
    let domain = unique_domain("ign");
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "up",
            "--launch",
            launch.to_str().expect("utf-8 path"),
            "--duration",
            "2s",
        ],
        Duration::from_secs(60),
    );
    assert!(status.success(), "{stderr}");
    assert!(stderr.contains("did not stop in time: SIGKILL"), "{stderr}");
    assert!(stderr.contains("killed by SIGKILL"), "{stderr}");
    // The killed process's node was cleaned up by the supervisor.
    assert_eq!(leftover_files(&domain), "");
}

#[test]
fn malformed_launch_files_name_file_line_and_key() {
    let dir = TempDir::new("badlaunch");
    let cases = [
        (
            "unknown_key.toml",
            "[[process]]\nname = \"a\"\ncommand = \"camera\"\nrestrat = \"never\"\n",
            "restrat",
        ),
        (
            "bad_policy.toml",
            "[[process]]\nname = \"a\"\ncommand = \"camera\"\nrestart = \"sometimes\"\n",
            "sometimes",
        ),
        (
            "unknown_process.toml",
            "[[process]]\nname = \"a\"\ncommand = \"cammera\"\n",
            "unknown command \"cammera\"",
        ),
        (
            "duplicate.toml",
            "[[process]]\nname = \"a\"\ncommand = \"camera\"\n\n[[process]]\nname = \"a\"\ncommand = \"camera\"\n",
            "duplicate process name \"a\"",
        ),
    ];
    for (file, text, expected) in cases {
        let path = dir.write(file, text);
        let (status, _, stderr) = run_harvest(
            &unique_domain("bad"),
            &["up", "--launch", path.to_str().expect("utf-8 path")],
            Duration::from_secs(30),
        );
        assert!(!status.success(), "{file}: {stderr}");
        assert!(stderr.contains(file), "{file} not named: {stderr}");
        assert!(stderr.contains("line "), "{file}: no line: {stderr}");
        assert!(
            stderr.contains(expected),
            "{file}: {expected:?} missing: {stderr}"
        );
    }
}

#[test]
fn unknown_subcommand_prints_help() {
    let (status, _, stderr) =
        run_harvest(&unique_domain("help"), &["fly"], Duration::from_secs(30));
    assert!(!status.success());
    assert!(
        stderr.contains("unrecognized subcommand") && stderr.contains("Usage"),
        "{stderr}"
    );
}
