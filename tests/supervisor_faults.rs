//! Supervisor behaviour with fault-injection fixtures: real processes, real shared memory.

mod common;

use common::*;
use std::process::ExitStatus;
use std::time::Duration;

/// Runs `harvest up --launch <tag>.toml --duration <duration>` on a fresh domain, the launch
/// file holding `launch_toml`; returns the exit status, stderr and the domain (for
/// [`leftover_files`]).
fn up_with_launch(
    tag: &str,
    launch_toml: &str,
    duration: &str,
) -> (ExitStatus, String, common::TestDomain) {
    let dir = TempDir::new(tag);
    let launch = dir.write(&format!("{tag}.toml"), launch_toml);
    let domain = unique_domain(tag);
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "up",
            "--launch",
            launch.to_str().expect("utf-8 path"),
            "--duration",
            duration,
        ],
        Duration::from_secs(60),
    );
    (status, stderr, domain)
}

#[test]
fn crash_at_start_exhausts_restart_budget_and_exits_nonzero() {
    let fixture = fixture_executable();
    let (status, stderr, domain) = up_with_launch(
        "crash",
        &format!(
            "[[process]]\nname = \"crasher\"\nexecutable = \"{fixture}\"\nargs = [\"always-crash\"]\n\
         restart = \"on-failure\"\nmax_restarts = 2\nbackoff_initial_ms = 50\nbackoff_max_ms = 100\n"
        ),
        "20s",
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
    let fixture = fixture_executable();
    let (status, stderr, domain) = up_with_launch(
        "hang",
        &format!(
            "[stack]\nhang_timeout_ms = 1500\nstartup_grace_ms = 1500\n\n[[process]]\nname = \"hanger\"\n\
         executable = \"{fixture}\"\nargs = [\"hang-after-init\"]\nrestart = \"on-failure\"\n\
         max_restarts = 10\nbackoff_initial_ms = 50\n"
        ),
        "7s",
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
    let fixture = fixture_executable();
    let (status, stderr, domain) = up_with_launch(
        "ignore",
        &format!(
            "[stack]\nshutdown_grace_ms = 500\n\n[[process]]\nname = \"stubborn\"\nexecutable = \"{fixture}\"\n\
         args = [\"ignore-sigterm\"]\n"
        ),
        "2s",
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
