//! Room on `camera/rgbd` with the real processes over real shared memory:
//! - on a running camera (the simulated robot and the camera driver), subscribers up to the
//!   channel's limit all receive; one more is refused with an error naming the channel and the
//!   limit, and the others keep receiving;
//! - the stack's four frame readers (perception, recorder, Foxglove bridge, console) start
//!   while four tools already read the channel (`harvest bench pipeline --attach` and three
//!   readers of this test): nothing is refused, no reader restarts, and `harvest up` ends
//!   only when asked, with no process failed (a benchmark beside the stack could end it when
//!   the channel had room for four readers).

mod common;

use common::webdriver::free_port;
use common::*;
use harvest_ipc::catalogue::{CAMERA_RGBD, PROCESS_HEALTH};
use harvest_ipc::error::{OpenChannelError, PortKind};
use harvest_ipc::payloads::{ProcessRunState, RgbdFrame};
use harvest_ipc::{Context, Domain, Subscriber};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// The simulated robot's camera at a low rate (these tests are about ports, not frame rates).
fn camera_launch(rate_hz: u32) -> String {
    format!(
        r#"
[stack]
startup_grace_ms = 20000
hang_timeout_ms = 5000

[[process]]
name = "sim"
command = "sim"
args = ["--scenario", "default", "--seed", "1", "--camera-rate-hz", "{rate_hz}"]

[[process]]
name = "camera"
command = "camera"
"#
    )
}

/// Frames received by each subscriber within `limit` (drained as they come).
fn frames_received(subscribers: &[Subscriber<RgbdFrame>], limit: Duration) -> Vec<u64> {
    let mut counts = vec![0u64; subscribers.len()];
    let deadline = Instant::now() + limit;
    while Instant::now() < deadline && counts.iter().any(|&n| n < 2) {
        for (subscriber, count) in subscribers.iter().zip(counts.iter_mut()) {
            while let Ok(Some(_frame)) = subscriber.receive() {
                *count += 1;
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    counts
}

fn assert_refused_ninth(context: &Context) {
    let limit = CAMERA_RGBD.spec.qos.max_subscribers;
    match context.subscriber(CAMERA_RGBD) {
        Err(error @ OpenChannelError::PortLimit { .. }) => {
            let OpenChannelError::PortLimit {
                topic,
                port,
                limit: said,
            } = &error
            else {
                unreachable!()
            };
            assert_eq!(
                (*topic, *port, *said),
                ("camera/rgbd", PortKind::Subscriber, limit)
            );
            let text = error.to_string();
            assert!(
                text.contains("\"camera/rgbd\"") && text.contains(&format!("allows {limit}")),
                "{text}"
            );
        }
        Err(other) => panic!("expected the subscriber limit, got {other}"),
        Ok(_) => panic!("a subscriber beyond the limit of {limit} was accepted"),
    }
}

#[test]
fn readers_up_to_the_limit_receive_and_one_more_is_refused_by_name() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("frameroom");
    let dir = TempDir::new("frameroom");
    let launch = dir.write("camera.toml", &camera_launch(4));
    let stack = Drained::spawn(
        &domain,
        &["up", "--launch", launch.to_str().expect("utf-8")],
    );

    let context =
        Context::new(&Domain::new(&domain).expect("domain"), "frame-room-test").expect("context");
    let limit = CAMERA_RGBD.spec.qos.max_subscribers;
    assert!(limit >= 8, "the stack's 4 readers and 4 tools");
    let subscribers: Vec<Subscriber<RgbdFrame>> = (0..limit)
        .map(|i| {
            context
                .subscriber(CAMERA_RGBD)
                .unwrap_or_else(|error| panic!("subscriber {i}: {error}"))
        })
        .collect();
    let counts = frames_received(&subscribers, Duration::from_secs(90));
    assert!(
        counts.iter().all(|&n| n >= 2),
        "frames per reader: {counts:?}"
    );

    assert_refused_ninth(&context);
    // The refused port changed nothing: every reader goes on receiving.
    let counts = frames_received(&subscribers, Duration::from_secs(30));
    assert!(
        counts.iter().all(|&n| n >= 2),
        "frames per reader after the refusal: {counts:?}"
    );

    drop(subscribers);
    drop(context);
    let (status, _, stderr) = stack.interrupt_and_wait(Duration::from_secs(60));
    assert!(status.success(), "{stderr}");
    assert_eq!(summary_restarts(&stderr, "camera"), Some(0), "{stderr}");
    assert_eq!(leftover_files(&domain), "");
}

#[test]
fn a_benchmark_and_three_more_tools_beside_the_stack_cannot_end_it() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("fourtools");
    let dir = TempDir::new("fourtools");
    let calibration = SIM_CAMERA_CALIBRATION;
    let mut text = camera_launch(5);
    text.push_str(&format!(
        r#"
[[process]]
name = "perception"
command = "perception"
args = ["--calibration", "{calibration}"]

[[process]]
name = "recorder"
command = "recorder"
args = ["--output-dir", "recordings", "--include", "camera/rgbd"]

[[process]]
name = "foxglove"
command = "foxglove"
args = ["--calibration", "{calibration}", "--listen", "127.0.0.1:{fox_port}"]

[[process]]
name = "console"
command = "console"
args = ["--listen", "127.0.0.1:{console_port}"]
"#,
        fox_port = free_port(),
        console_port = free_port(),
    ));
    let launch = dir.write("stack.toml", &text);

    // Three tools read the channel before the stack starts (a second viewer, a monitor, a
    // replay check), the benchmark attaches while it starts.
    let context =
        Context::new(&Domain::new(&domain).expect("domain"), "four-tools-test").expect("context");
    let tools: Vec<Subscriber<RgbdFrame>> = (0..3)
        .map(|_| context.subscriber(CAMERA_RGBD).expect("tool reader"))
        .collect();
    let health = context
        .subscriber_with_buffer(PROCESS_HEALTH, 256)
        .expect("health");
    let stack = Drained::spawn(
        &domain,
        &[
            "up",
            "--launch",
            launch.to_str().expect("utf-8"),
            "--duration",
            "150s",
        ],
    );
    let bench = Drained::spawn(
        &domain,
        &[
            "bench",
            "pipeline",
            "--attach",
            "--warmup",
            "1s",
            "--duration",
            "600s",
        ],
    );

    // Every frame reader of the stack runs (one pid each: no restart) while the tools read.
    let readers = ["perception", "recorder", "foxglove", "console"];
    let mut pids: BTreeMap<String, Vec<u32>> = BTreeMap::new();
    let deadline = Instant::now() + Duration::from_secs(120);
    loop {
        while let Ok(Some(beat)) = health.receive() {
            let name = beat.process_name.as_str().to_owned();
            assert_ne!(
                beat.run_state.get().ok(),
                Some(ProcessRunState::Failed),
                "{name} failed for good"
            );
            let seen = pids.entry(name).or_default();
            if !seen.contains(&beat.pid) {
                seen.push(beat.pid);
            }
        }
        if readers.iter().all(|r| pids.contains_key(*r)) {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "watchdog: not every frame reader heard from: {pids:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let counts = frames_received(&tools, Duration::from_secs(60));
    assert!(
        counts.iter().all(|&n| n >= 2),
        "frames per tool: {counts:?}"
    );
    // Eight readers now: the stack's four, the benchmark and this test's three. A ninth is
    // refused by name and harms nothing.
    assert_refused_ninth(&context);
    let counts = frames_received(&tools, Duration::from_secs(30));
    assert!(
        counts.iter().all(|&n| n >= 2),
        "frames per tool: {counts:?}"
    );
    // A few more seconds of the stack beside its tools, watching for restarts.
    let watch_until = Instant::now() + Duration::from_secs(5);
    while Instant::now() < watch_until {
        while let Ok(Some(beat)) = health.receive() {
            let seen = pids
                .entry(beat.process_name.as_str().to_owned())
                .or_default();
            if !seen.contains(&beat.pid) {
                seen.push(beat.pid);
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    for reader in readers {
        assert_eq!(pids[reader].len(), 1, "{reader} restarted: {pids:?}");
    }

    let (_, _, bench_stderr) = bench.interrupt_and_wait(Duration::from_secs(60));
    drop(tools);
    drop(health);
    drop(context);
    let (status, _, stderr) = stack.interrupt_and_wait(Duration::from_secs(60));
    assert!(status.success(), "{stderr}\nbench:\n{bench_stderr}");
    assert!(
        stderr.contains("harvest up ended: SIGINT/SIGTERM"),
        "{stderr}"
    );
    assert!(!stderr.contains("FAILED"), "{stderr}");
    for reader in readers {
        assert_eq!(summary_restarts(&stderr, reader), Some(0), "{stderr}");
    }
    assert_eq!(leftover_files(&domain), "");
}
