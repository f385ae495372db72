//! `harvest ctl` against a real `harvest executive` in a private domain (no robot: the commands
//! that need no arm, and the refusals of those that do). The token comes from the domain's
//! token file, as `harvest up` writes it; the e-stop is checked on `safety/emergency_stop`.

mod common;

use common::{HARVEST, TempDir, leftover_files, run_dir, unique_domain, wait_with_watchdog};
use harvest_ipc::catalogue::EMERGENCY_STOP;
use harvest_ipc::{Context, Domain};
use harvest_operator::ControlToken;
use harvest_operator::token::write_token_file;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Where `harvest_operator::token::token_path` puts the token file with `XDG_RUNTIME_DIR` set.
fn token_path_in(runtime: &std::path::Path, domain: &str) -> std::path::PathBuf {
    runtime.join("harvest").join(format!("{domain}.token"))
}

/// Runs `harvest ctl <args>` in `domain` with the token files under `runtime`.
fn ctl(domain: &str, runtime: &std::path::Path, args: &[&str]) -> Output {
    Command::new(HARVEST)
        .arg("ctl")
        .args(args)
        .env("HARVEST_DOMAIN", domain)
        .env("XDG_RUNTIME_DIR", runtime)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .output()
        .expect("run harvest ctl")
}

fn text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

#[test]
fn ctl_commands_the_executive_and_prints_its_answers() {
    let domain = unique_domain("ctl");
    let runtime = TempDir::new("ctl-runtime");
    // The token file as `harvest up` writes it (XDG_RUNTIME_DIR/harvest/<domain>.token).
    let token = ControlToken::generate().expect("token");
    let path = token_path_in(&runtime.0, &domain);
    write_token_file(&path, &token).expect("token file");

    let executive = Command::new(HARVEST)
        .args(["executive", "--platform", "none", "--initial-mode", "idle"])
        .current_dir(run_dir(&domain))
        .env("HARVEST_DOMAIN", &domain)
        .env("XDG_RUNTIME_DIR", &runtime.0)
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the executive");

    // Status needs no token; wait (watchdog) for the executive's first mode.
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        let output = ctl(&domain, &runtime.0, &["status", "--json"]);
        if output.status.success() {
            break output;
        }
        assert!(Instant::now() < deadline, "no status: {}", text(&output));
    };
    let value: serde_json::Value = serde_json::from_slice(&status.stdout).expect("json");
    assert_eq!(value["mode"], "idle");

    // Refused: forbidden by the mode, wrong token, motions without arms or platform.
    let pause = ctl(&domain, &runtime.0, &["pause"]);
    assert_eq!(pause.status.code(), Some(1), "{}", text(&pause));
    assert!(
        text(&pause).contains("`pause` is not allowed while idle"),
        "{}",
        text(&pause)
    );
    let wrong = ctl(
        &domain,
        &runtime.0,
        &["start", "--token", "0123456789abcdef0123456789abcdef"],
    );
    assert_eq!(wrong.status.code(), Some(1));
    assert!(
        text(&wrong).contains("wrong control token"),
        "{}",
        text(&wrong)
    );
    let jog = ctl(
        &domain,
        &runtime.0,
        &["jog", "--arm", "1", "--joint", "theta", "--delta", "0.05"],
    );
    assert_eq!(jog.status.code(), Some(1));
    assert!(
        text(&jog).contains("arm 1: no recent state"),
        "{}",
        text(&jog)
    );
    let platform = ctl(
        &domain,
        &runtime.0,
        &["platform", "--in-out", "0.1", "--up-down", "0.1"],
    );
    assert_eq!(platform.status.code(), Some(1));
    assert!(
        text(&platform).contains("no platform device"),
        "{}",
        text(&platform)
    );
    // "Next stop" with no row configured (no `--row-stops`): refused with the reason, exit 1.
    let next_stop = ctl(&domain, &runtime.0, &["next-stop"]);
    assert_eq!(next_stop.status.code(), Some(1), "{}", text(&next_stop));
    assert!(
        text(&next_stop).contains("no row configured"),
        "{}",
        text(&next_stop)
    );
    let bad_joint = ctl(
        &domain,
        &runtime.0,
        &["jog", "--arm", "1", "--joint", "elbow", "--delta", "0.05"],
    );
    assert_eq!(bad_joint.status.code(), Some(2), "clap refuses it");

    // Accepted: start, then the e-stop on the channel, release, arm disable.
    let start = ctl(&domain, &runtime.0, &["start"]);
    assert!(start.status.success(), "{}", text(&start));
    assert!(text(&start).contains("start: accepted"), "{}", text(&start));
    let context = Context::new(&Domain::new(&domain).expect("domain"), "ctl-test").expect("node");
    let estop_in = context.subscriber(EMERGENCY_STOP).expect("estop");
    let estop = ctl(&domain, &runtime.0, &["estop"]);
    assert!(estop.status.success(), "{}", text(&estop));
    let mut engaged = None;
    let deadline = Instant::now() + Duration::from_secs(5);
    while engaged.is_none() {
        if let Some(sample) = estop_in.receive_latest().expect("receive") {
            engaged = Some(sample.engaged);
        }
        assert!(
            Instant::now() < deadline,
            "no emergency stop on the channel"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(engaged, Some(1));
    let start_while_stopped = ctl(&domain, &runtime.0, &["start"]);
    assert_eq!(start_while_stopped.status.code(), Some(1));
    assert!(text(&start_while_stopped).contains("release the emergency stop first"));
    let release = ctl(&domain, &runtime.0, &["release"]);
    assert!(release.status.success(), "{}", text(&release));
    let disable = ctl(&domain, &runtime.0, &["arm", "2", "disable"]);
    assert!(disable.status.success(), "{}", text(&disable));
    let status = ctl(&domain, &runtime.0, &["status"]);
    assert!(
        text(&status).contains("mode idle; arms enabled 1/0; e-stop released"),
        "{}",
        text(&status)
    );

    // No executive in another domain: no answer, exit code 2.
    let elsewhere = unique_domain("ctlnone");
    write_token_file(&token_path_in(&runtime.0, &elsewhere), &token).expect("token file");
    let silent = ctl(&elsewhere, &runtime.0, &["--timeout-ms", "300", "stop"]);
    assert_eq!(silent.status.code(), Some(2), "{}", text(&silent));
    assert!(text(&silent).contains("no answer"), "{}", text(&silent));

    drop(estop_in);
    drop(context);
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(executive.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    )
    .expect("stop the executive");
    let (exit, _, stderr) = wait_with_watchdog(executive, Duration::from_secs(20));
    assert!(exit.success(), "{stderr}");
    assert_eq!(leftover_files(&domain), "");
    let _ = leftover_files(&elsewhere);
}

/// `harvest ctl estop` needs no authority: without any token (no file, none given) or with a
/// wrong one, the executive engages the stop; the release still needs the token.
#[test]
fn ctl_estop_needs_no_token_and_the_release_does() {
    let domain = unique_domain("ctlstop");
    let runtime = TempDir::new("ctlstop-runtime");
    // The executive's token file; `ctl` runs with another runtime directory, without any.
    let token = ControlToken::generate().expect("token");
    write_token_file(&token_path_in(&runtime.0, &domain), &token).expect("token file");
    let no_token = TempDir::new("ctlstop-none");

    let executive = Command::new(HARVEST)
        .args([
            "executive",
            "--platform",
            "none",
            "--initial-mode",
            "harvesting",
        ])
        .current_dir(run_dir(&domain))
        .env("HARVEST_DOMAIN", &domain)
        .env("XDG_RUNTIME_DIR", &runtime.0)
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the executive");
    let context = Context::new(&Domain::new(&domain).expect("domain"), "ctl-test").expect("node");
    let estop_in = context.subscriber(EMERGENCY_STOP).expect("estop");
    let engaged = |want: u8| {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Some(sample) = estop_in.receive_latest().expect("receive")
                && sample.engaged == want
            {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "watchdog: e-stop engaged {want} not seen"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let output = ctl(&domain, &no_token.0, &["status", "--json"]);
        if output.status.success() {
            break;
        }
        assert!(Instant::now() < deadline, "no status: {}", text(&output));
    }

    // Without any token: the token file is missing, ctl says so and sends the stop anyway.
    let start = ctl(&domain, &no_token.0, &["start"]);
    assert!(!start.status.success(), "{}", text(&start));
    let estop = ctl(&domain, &no_token.0, &["estop"]);
    assert!(estop.status.success(), "{}", text(&estop));
    assert!(
        text(&estop).contains("sent without it") && text(&estop).contains("estop: accepted"),
        "{}",
        text(&estop)
    );
    engaged(1);
    // The release with a wrong token is refused; the stop stays engaged.
    let release = ctl(&domain, &no_token.0, &["release", "--token", WRONG]);
    assert_eq!(release.status.code(), Some(1), "{}", text(&release));
    assert!(
        text(&release).contains("wrong control token"),
        "{}",
        text(&release)
    );
    let status = ctl(&domain, &no_token.0, &["status"]);
    assert!(
        text(&status).contains("e-stop ENGAGED")
            && text(&status).contains("without the control token"),
        "{}",
        text(&status)
    );
    // Released with the token: idle.
    let release = ctl(&domain, &runtime.0, &["release"]);
    assert!(release.status.success(), "{}", text(&release));
    engaged(0);
    // A wrong token stops it too.
    let estop = ctl(&domain, &no_token.0, &["estop", "--token", WRONG]);
    assert!(estop.status.success(), "{}", text(&estop));
    engaged(1);

    drop(estop_in);
    drop(context);
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(executive.id() as i32),
        nix::sys::signal::Signal::SIGTERM,
    )
    .expect("stop the executive");
    let (exit, _, stderr) = wait_with_watchdog(executive, Duration::from_secs(20));
    assert!(exit.success(), "{stderr}");
    assert_eq!(leftover_files(&domain), "");
}

const WRONG: &str = "0123456789abcdef0123456789abcdef";
