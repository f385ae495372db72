//! The console's emergency stop against a real `harvest executive` and a real `harvest console`
//! in a private domain, through the console's HTTP API (what the page posts):
//! - the stop needs no authority: a wrong token stops the robot, a wrong token cannot release it;
//! - the stop goes out at once while another command's answer is pending (the executive is
//!   stalled with SIGSTOP while a jog waits for its answer) and engages as soon as the executive
//!   runs again;
//! - when the console cannot open the operator channels (every `operator/command` publisher
//!   slot taken), its status says it cannot reach the executive and a command is answered at
//!   once with the reason; once the slots are free the console reaches the executive again.

mod common;

use common::console::{post_command, status, wait_until};
use common::webdriver::free_port;
use common::{HARVEST, TempDir, leftover_files, run_dir, unique_domain, wait_with_watchdog};
use harvest_ipc::catalogue::{EMERGENCY_STOP, OPERATOR_COMMAND};
use harvest_ipc::payloads::{EmergencyStop, OperatorCommand, OperatorCommandCode};
use harvest_ipc::{Context, Domain, Subscriber};
use harvest_operator::ControlToken;
use harvest_operator::token::write_token_file;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use serde_json::{Value, json};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

fn spawn(domain: &str, runtime: &std::path::Path, args: &[&str]) -> Child {
    Command::new(HARVEST)
        .args(args)
        .current_dir(run_dir(domain))
        .env("HARVEST_DOMAIN", domain)
        .env("XDG_RUNTIME_DIR", runtime)
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn harvest")
}

/// Posts on a thread of its own; the answer comes on the receiver.
fn post_in_background(
    port: u16,
    token: &str,
    session: u64,
    command: Value,
) -> mpsc::Receiver<(u16, Value)> {
    let (done, answer) = mpsc::channel();
    let token = token.to_owned();
    std::thread::spawn(move || {
        let _ = done.send(post_command(port, &token, session, command));
    });
    answer
}

/// The commands seen on `operator/command` so far.
fn drain_commands(commands: &Subscriber<OperatorCommand>, seen: &mut Vec<OperatorCommand>) {
    while let Ok(Some(command)) = commands.receive() {
        seen.push(*command);
    }
}

/// Whether the stop is engaged, as last published (`last` keeps it between calls).
fn engaged(estop: &Subscriber<EmergencyStop>, last: &mut Option<bool>) -> Option<bool> {
    if let Ok(Some(sample)) = estop.receive_latest() {
        *last = Some(sample.engaged == 1);
    }
    *last
}

const WRONG_TOKEN: &str = "0123456789abcdef0123456789abcdef";

#[test]
fn the_console_stop_needs_no_authority_and_never_waits_behind_another_command() {
    let domain = unique_domain("cestop");
    let runtime = TempDir::new("cestop-runtime");
    // The token file as `harvest up` writes it (XDG_RUNTIME_DIR/harvest/<domain>.token), for
    // the executive.
    let token = ControlToken::generate().expect("token");
    let path = runtime.0.join("harvest").join(format!("{domain}.token"));
    write_token_file(&path, &token).expect("token file");
    let token = token.as_str().to_owned();
    let ipc_domain = Domain::new(&domain).expect("domain");
    let context = Context::new(&ipc_domain, "console-estop-test").expect("context");

    // Every publisher slot of operator/command taken before the console starts: it cannot
    // open its lanes.
    let mut blockers = Vec::new();
    loop {
        match context.publisher(OPERATOR_COMMAND) {
            Ok(publisher) => blockers.push(publisher),
            Err(error) => {
                let text = error.to_string();
                assert!(text.contains("operator/command"), "{text}");
                break;
            }
        }
        assert!(
            blockers.len() <= 64,
            "no publisher limit on operator/command"
        );
    }
    assert_eq!(blockers.len(), OPERATOR_COMMAND.spec.qos.max_publishers);

    let executive = spawn(
        &domain,
        &runtime.0,
        &[
            "executive",
            "--platform",
            "none",
            "--initial-mode",
            "harvesting",
        ],
    );
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let console = spawn(
        &domain,
        &runtime.0,
        &["console", "--listen", &listen, "--ack-timeout-ms", "10000"],
    );
    let commands_in = context
        .subscriber_with_buffer(OPERATOR_COMMAND, 64)
        .expect("command subscriber");
    let estop_in = context
        .subscriber(EMERGENCY_STOP)
        .expect("estop subscriber");
    let mut stop_state = None;

    // The status says the console cannot reach the executive, with the channel's reason.
    wait_until(
        "the console's status naming both dead lanes",
        Duration::from_secs(60),
        || {
            status(port).is_some_and(|s| {
                s["mode"]["name"] == "harvesting"
                    && s["links"]["estop"]["ok"] == false
                    && s["links"]["commands"]["ok"] == false
            })
        },
    );
    let s = status(port).expect("status");
    let problem = s["links"]["estop"]["problem"].as_str().unwrap_or_default();
    assert!(
        problem.contains("operator/command") && problem.contains("publisher"),
        "{s}"
    );
    // A stop posted now is answered at once as unreachable (not left to time out).
    let (code, answer) = post_command(port, "", 7, json!({"command": "estop"}));
    assert_eq!(code, 503, "{answer}");
    assert_eq!(answer["unreachable"], true, "{answer}");
    assert!(
        answer["reason"]
            .as_str()
            .is_some_and(|r| r.contains("cannot reach the executive")),
        "{answer}"
    );
    assert_ne!(
        engaged(&estop_in, &mut stop_state),
        Some(true),
        "stopped by a command never sent"
    );

    // Slots free: both lanes reopen by themselves.
    drop(blockers);
    wait_until(
        "both console lanes open again",
        Duration::from_secs(20),
        || {
            status(port).is_some_and(|s| {
                s["links"]["estop"]["ok"] == true && s["links"]["commands"]["ok"] == true
            })
        },
    );

    // A wrong token: the stop is taken all the same (and from a session that does not control).
    let (code, answer) = post_command(port, "", 11, json!({"command": "heartbeat"}));
    assert_eq!(
        (code, answer["accepted"].clone()),
        (200, json!(false)),
        "{answer}"
    );
    let (code, answer) = post_command(port, WRONG_TOKEN, 12, json!({"command": "estop"}));
    assert_eq!(code, 200, "{answer}");
    assert_eq!(answer["accepted"], true, "{answer}");
    wait_until(
        "the emergency stop engaged",
        Duration::from_secs(10),
        || engaged(&estop_in, &mut stop_state) == Some(true),
    );
    // The release with a wrong token (or none) is refused; the stop stays engaged.
    for bad in [WRONG_TOKEN, ""] {
        let (code, answer) = post_command(port, bad, 12, json!({"command": "release"}));
        assert_eq!(code, 200, "{answer}");
        assert_eq!(answer["accepted"], false, "{answer}");
        assert!(
            matches!(
                answer["refusal"].as_str(),
                Some("WrongToken" | "MissingToken")
            ),
            "{answer}"
        );
    }
    assert_eq!(engaged(&estop_in, &mut stop_state), Some(true));
    wait_until("estopped on the console", Duration::from_secs(10), || {
        status(port).is_some_and(|s| s["mode"]["name"] == "estopped")
    });
    // With the token: released, idle.
    let (_, answer) = post_command(port, &token, 1, json!({"command": "release"}));
    assert_eq!(answer["accepted"], true, "{answer}");
    assert_eq!(answer["mode"], "idle", "{answer}");
    wait_until("the stop released", Duration::from_secs(10), || {
        engaged(&estop_in, &mut stop_state) == Some(false)
    });

    // The stop while a jog's answer is pending: the executive is stalled (SIGSTOP), the jog
    // waits for its answer on the command lane, the stop goes out on its own lane at once.
    let mut seen = Vec::new();
    drain_commands(&commands_in, &mut seen);
    seen.clear();
    kill(Pid::from_raw(executive.id() as i32), Signal::SIGSTOP).expect("stall the executive");
    let jog = post_in_background(
        port,
        &token,
        1,
        json!({"command": "jog", "arm": 1, "joint": "theta", "delta": 0.05}),
    );
    let has = |seen: &[OperatorCommand], code: OperatorCommandCode| {
        seen.iter().any(|c| c.command_code() == Some(code))
    };
    wait_until(
        "the jog on operator/command",
        Duration::from_secs(10),
        || {
            drain_commands(&commands_in, &mut seen);
            has(&seen, OperatorCommandCode::Jog)
        },
    );
    let estop = post_in_background(port, "", 13, json!({"command": "estop"}));
    wait_until(
        "the stop on operator/command",
        Duration::from_secs(10),
        || {
            drain_commands(&commands_in, &mut seen);
            has(&seen, OperatorCommandCode::EmergencyStop)
        },
    );
    assert!(
        jog.try_recv().is_err(),
        "the jog was answered while the executive was stalled"
    );
    kill(Pid::from_raw(executive.id() as i32), Signal::SIGCONT).expect("resume the executive");
    wait_until(
        "the emergency stop engaged after the executive resumed",
        Duration::from_secs(10),
        || engaged(&estop_in, &mut stop_state) == Some(true),
    );
    let (code, answer) = estop.recv_timeout(Duration::from_secs(30)).expect("answer");
    assert_eq!(code, 200, "{answer}");
    assert_eq!(answer["accepted"], true, "{answer}");
    let (code, answer) = jog
        .recv_timeout(Duration::from_secs(30))
        .expect("jog answer");
    assert_eq!(code, 200, "the jog got its answer too: {answer}");

    drop((commands_in, estop_in));
    drop(context);
    for child in [console, executive] {
        kill(Pid::from_raw(child.id() as i32), Signal::SIGTERM).expect("stop");
        let (exit, _, stderr) = wait_with_watchdog(child, Duration::from_secs(20));
        assert!(exit.success(), "{stderr}");
    }
    assert_eq!(leftover_files(&domain), "");
}
