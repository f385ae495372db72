//! The console under load against a real stack (sim, camera, both arms, executive, console in a
//! private domain): 21 watching pages (each from a loopback address of its own, as devices on
//! the field network; one of them a slow reader that takes nothing), a 22nd watcher refused
//! because the watchers' share is full, 50 half-open connections from one address, and the
//! operator's page, which is admitted beyond the watchers' share because it controls:
//! - every watcher gets the status and camera views pushed;
//! - the controlling page's e-stop (sent without a token over its push connection) engages
//!   the stop and both arms stop (on the arms' state channels);
//! - the half-open connections beyond the address's bound are refused at once, the others
//!   closed by the header timeout; the slow reader is dropped.
//!
//! Prints the e-stop's send-to-braked times; nothing is asserted about timing (the benchmark
//! `harvest bench console` measures).

mod common;

use common::console::{
    control_token, post_command, status, wait_for_harvesting_console, wait_until,
};
use common::webdriver::free_port;
use common::{
    TempDir, leftover_files, one_stack_at_a_time, spawn_harvest, unique_domain, wait_with_watchdog,
};
use harvest_bench::console::live::{Live, LiveClient, LiveError, connect_from, open_live};
use harvest_bench::console::watched_stack_launch;
use harvest_ipc::catalogue::{ARM_STATE, EMERGENCY_STOP};
use harvest_ipc::payloads::ArmPhase;
use harvest_ipc::{Context, Domain, MonotonicClock};
use serde_json::{Value, json};
use std::io::{Read, Write};
use std::net::{Ipv4Addr, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const WATCHERS: usize = 20;
const HALF_OPEN: usize = 50;
/// The console's bound of connections per address in this test (the default).
const PER_ADDRESS: usize = 32;

/// What one watcher has received.
#[derive(Debug, Default, Clone, Copy)]
struct Seen {
    statuses: u64,
    views: u64,
    jpegs_ok: u64,
}

fn watch(mut client: LiveClient, seen: Arc<Mutex<Seen>>, stop: Arc<AtomicBool>) {
    while !stop.load(Ordering::Acquire) {
        match client.next(Duration::from_millis(200)).expect("watching") {
            Some(Live::Status(_)) => seen.lock().unwrap().statuses += 1,
            Some(Live::View { jpeg, .. }) => {
                let mut seen = seen.lock().unwrap();
                seen.views += 1;
                if jpeg.starts_with(&[0xff, 0xd8]) && jpeg.ends_with(&[0xff, 0xd9]) {
                    seen.jpegs_ok += 1;
                }
            }
            _ => {}
        }
    }
}

#[test]
fn the_operator_stops_the_arms_through_a_console_full_of_watchers() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("cload");
    let port = free_port();
    let dir = TempDir::new("cload");
    let launch = dir.write(
        "console-load.toml",
        &watched_stack_launch(port, 10.0, WATCHERS + 1),
    );
    let stack = spawn_harvest(
        &domain,
        &["up", "--launch", launch.to_str().expect("utf-8")],
    );
    let token = control_token(&domain);
    wait_for_harvesting_console(port);
    let ipc_domain = Domain::new(&domain).expect("domain");
    let context = Context::new(&ipc_domain, "console-load-test").expect("context");
    let estop_in = context.subscriber(EMERGENCY_STOP).expect("estop");
    let states_in = [0, 1].map(|i| {
        context
            .subscriber_with_buffer(ARM_STATE[i], 256)
            .expect("arm state")
    });

    // The operator takes control with a plain POST and keeps it with heartbeats (the
    // executive drops a session silent for 500 ms) until its push connection is open.
    let session: u64 = 4_242_424_242;
    let (code, answer) = post_command(port, &token, session, json!({"command": "heartbeat"}));
    assert_eq!(
        (code, answer["accepted"].clone()),
        (200, json!(true)),
        "{answer}"
    );
    let posting = Arc::new(AtomicBool::new(true));
    let poster = {
        let (posting, token) = (posting.clone(), token.clone());
        std::thread::spawn(move || {
            while posting.load(Ordering::Acquire) {
                post_command(port, &token, session, json!({"command": "heartbeat"}));
                std::thread::sleep(Duration::from_millis(150));
            }
        })
    };
    // The status carries the session id as text (a u64 does not fit a JSON number exactly).
    let session_text = session.to_string();
    wait_until(
        "the console knowing the controlling session",
        Duration::from_secs(10),
        || status(port).is_some_and(|s| s["mode"]["controlling_session"] == session_text.as_str()),
    );

    // The watchers fill their share: 20 pages and a slow reader (a 4 KiB receive buffer it
    // never reads), each from an address of its own.
    let stop = Arc::new(AtomicBool::new(false));
    let mut watchers = Vec::new();
    let mut seen = Vec::new();
    for k in 0..WATCHERS {
        let address = Ipv4Addr::new(127, 0, 1, 10 + k as u8);
        let client = open_live(address, port, 1000 + k as u64, None).expect("a watcher admitted");
        let counts = Arc::new(Mutex::new(Seen::default()));
        seen.push(counts.clone());
        let stop = stop.clone();
        watchers.push(std::thread::spawn(move || watch(client, counts, stop)));
    }
    let slow_reader = open_live(Ipv4Addr::new(127, 0, 2, 1), port, 999, Some(4096))
        .expect("the slow reader admitted");
    // The share is full: one more watcher is refused.
    assert_eq!(
        open_live(Ipv4Addr::new(127, 0, 2, 2), port, 998, None).err(),
        Some(LiveError::Refused(503)),
        "a watcher beyond the share was admitted"
    );

    // 50 half-open connections from one address: a request head that never ends.
    let mut half_open: Vec<TcpStream> = (0..HALF_OPEN)
        .map(|_| {
            let mut stream =
                connect_from(Ipv4Addr::new(127, 0, 3, 1), port, None).expect("connect");
            let _ = stream.write_all(b"GET /api/status HTTP/1.1\r\nHost: console\r\n");
            stream
        })
        .collect();

    // The controlling page's push connection: admitted although the watchers' share is full.
    let mut operator = open_live(Ipv4Addr::LOCALHOST, port, session, None)
        .expect("the controlling page admitted beyond the watchers' share");
    posting.store(false, Ordering::Release);
    poster.join().expect("poster");
    // Heartbeats over the push connection from now on; the answers prove the path works.
    let mut next_id = 1u64;
    let heartbeat = |operator: &mut LiveClient, next_id: &mut u64| {
        operator
            .send(
                &json!({"op": "command", "id": *next_id, "token": token, "session": session,
                "command": {"command": "heartbeat"}}),
            )
            .expect("heartbeat");
        *next_id += 1;
    };
    let mut answers: Vec<Value> = Vec::new();
    let settle_until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < settle_until {
        heartbeat(&mut operator, &mut next_id);
        let pause_until = Instant::now() + Duration::from_millis(150);
        while let Some(message) = operator
            .next(pause_until.saturating_duration_since(Instant::now()))
            .expect("operator")
        {
            if let Live::Answer(answer) = message {
                answers.push(answer);
            }
            if Instant::now() >= pause_until {
                break;
            }
        }
    }
    assert!(
        answers.iter().any(|a| a["accepted"] == true),
        "no heartbeat accepted over the push connection: {answers:?}"
    );

    // Every watcher has the status and views pushed to it.
    wait_until(
        "every watcher seeing statuses and camera views",
        Duration::from_secs(20),
        || {
            seen.iter().all(|s| {
                let s = *s.lock().unwrap();
                s.statuses >= 3 && s.views >= 3 && s.jpegs_ok == s.views
            })
        },
    );

    // The e-stop, without a token, over the controlling page's push connection.
    for subscriber in &states_in {
        while let Ok(Some(state)) = subscriber.receive() {
            assert_ne!(
                state.phase,
                ArmPhase::Stopped,
                "an arm stopped before the e-stop"
            );
        }
    }
    let sent_ns = MonotonicClock::read_ns();
    let estop_id = 1_000_000;
    operator
        .send(
            &json!({"op": "command", "id": estop_id, "token": "", "session": session,
            "command": {"command": "estop"}}),
        )
        .expect("send the e-stop");
    let mut braked_ns: [Option<u64>; 2] = [None, None];
    let mut engaged = false;
    let mut estop_answer = None;
    wait_until(
        "the e-stop engaged and both arms stopped",
        Duration::from_secs(10),
        || {
            while let Ok(Some(sample)) = estop_in.receive() {
                engaged |= sample.engaged == 1;
            }
            for (i, subscriber) in states_in.iter().enumerate() {
                while let Ok(Some(state)) = subscriber.receive() {
                    if state.phase == ArmPhase::Stopped && braked_ns[i].is_none() {
                        braked_ns[i] = Some(state.header.capture_ns);
                    }
                }
            }
            while let Some(message) = operator.next(Duration::from_millis(1)).expect("operator") {
                if let Live::Answer(answer) = message
                    && answer["id"] == estop_id
                {
                    estop_answer = Some(answer);
                }
            }
            engaged && braked_ns.iter().all(Option::is_some)
        },
    );
    wait_until("the e-stop's answer", Duration::from_secs(10), || {
        while let Some(message) = operator.next(Duration::from_millis(20)).expect("operator") {
            if let Live::Answer(answer) = message
                && answer["id"] == estop_id
            {
                estop_answer = Some(answer);
            }
        }
        estop_answer.is_some()
    });
    let estop_answer = estop_answer.expect("answer");
    assert_eq!(estop_answer["accepted"], true, "{estop_answer}");
    println!(
        "console under load: e-stop sent to arm 1 stopped {:.1} ms, arm 2 {:.1} ms ({WATCHERS} \
watchers + a slow reader, {HALF_OPEN} half-open connections)",
        (braked_ns[0].unwrap_or(0) as f64 - sent_ns as f64) / 1e6,
        (braked_ns[1].unwrap_or(0) as f64 - sent_ns as f64) / 1e6,
    );

    // The half-open connections: those beyond the address's bound refused at once (503), the
    // others closed by the header timeout.
    let mut refused = 0;
    let mut closed = [false; HALF_OPEN];
    wait_until(
        "every half-open connection answered or closed",
        Duration::from_secs(30),
        || {
            for (k, stream) in half_open.iter_mut().enumerate() {
                if closed[k] {
                    continue;
                }
                stream
                    .set_read_timeout(Some(Duration::from_millis(5)))
                    .expect("timeout");
                let mut buffer = [0u8; 512];
                match stream.read(&mut buffer) {
                    Ok(0) => closed[k] = true,
                    Ok(n) => {
                        if buffer[..n].starts_with(b"HTTP/1.1 503") {
                            refused += 1;
                        }
                        closed[k] = true;
                    }
                    Err(error)
                        if matches!(
                            error.kind(),
                            std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                        ) => {}
                    Err(_) => closed[k] = true,
                }
            }
            closed.iter().all(|&c| c)
        },
    );
    assert_eq!(refused, HALF_OPEN - PER_ADDRESS, "refused at once");

    // The slow reader is dropped once it has taken nothing for the console's send bound.
    let views_skipped = Arc::new(AtomicU64::new(0));
    wait_until("the slow reader dropped", Duration::from_secs(60), || {
        status(port).is_some_and(|s| {
            views_skipped.store(
                s["console"]["views_skipped"].as_u64().unwrap_or(0),
                Ordering::Relaxed,
            );
            s["console"]["watchers"] == WATCHERS
        })
    });
    drop(slow_reader);
    println!(
        "console under load: {} views skipped for slow pages",
        views_skipped.load(Ordering::Relaxed)
    );

    // The stop stays engaged; the release needs the token.
    let (_, answer) = post_command(port, &token, session, json!({"command": "release"}));
    assert_eq!(answer["accepted"], true, "{answer}");

    stop.store(true, Ordering::Release);
    for watcher in watchers {
        watcher.join().expect("watcher");
    }
    drop(operator);
    drop((estop_in, states_in));
    drop(context);
    nix::sys::signal::kill(
        nix::unistd::Pid::from_raw(stack.id() as i32),
        nix::sys::signal::Signal::SIGINT,
    )
    .expect("stop the stack");
    let (exit, _stdout, stderr) = wait_with_watchdog(stack, Duration::from_secs(60));
    assert!(exit.success(), "harvest up failed: {stderr}");
    assert_eq!(leftover_files(&domain), "");
}
