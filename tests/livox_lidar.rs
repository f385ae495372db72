//! `harvest lidar --device livox` as its own process against the fake Mid-70
//! (`harvest-fake-mid70`, the Livox SDK 1 protocol over UDP on loopback), over real shared
//! memory: clouds on `lidar/points` at the window's rate, dropped packets counted in the
//! health heartbeat, a silent device reported (`Degraded`, `disconnected`) and reconnected when
//! it speaks again, a reboot of the device survived, and a clean stop on SIGINT. How fast the
//! silence is reported and the device reconnected is measured by `harvest bench lidar-livox`,
//! not asserted here.

mod common;

use common::*;
use harvest_hw::conformance::TestWatchdog;
use harvest_ipc::Context;
use harvest_ipc::catalogue::{LIDAR_POINTS, PROCESS_HEALTH};
use harvest_ipc::payloads::ProcessRunState;
use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

const FAKE: &str = env!("CARGO_BIN_EXE_harvest-fake-mid70");

struct Fake {
    child: Child,
    stdin: ChildStdin,
    port: u16,
}

impl Fake {
    fn start() -> Self {
        let mut child = Command::new(FAKE)
            .args(["--cmd-addr", "127.0.0.1:0"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn harvest-fake-mid70");
        let stdin = child.stdin.take().expect("stdin");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        stdout.read_line(&mut line).expect("first line");
        let port = line
            .trim()
            .strip_prefix("cmd_addr 127.0.0.1:")
            .and_then(|port| port.parse().ok())
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"));
        Self { child, stdin, port }
    }

    fn command(&mut self, line: &str) {
        writeln!(self.stdin, "{line}").expect("command the fake");
        self.stdin.flush().expect("flush");
    }
}

impl Drop for Fake {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The test's view of the `lidar` process: its clouds and its heartbeats.
struct Watch {
    context: Context,
}

#[derive(Debug, Clone, PartialEq)]
struct Beat {
    state: ProcessRunState,
    detail: String,
    value: u64,
}

impl Watch {
    /// Waits until a heartbeat of `lidar` satisfies `want`; panics after `limit`.
    fn heartbeat(&self, limit: Duration, want: impl Fn(&Beat) -> bool) -> (Beat, Duration) {
        let health = self.context.subscriber(PROCESS_HEALTH).expect("health");
        let start = Instant::now();
        let mut last = None;
        while start.elapsed() < limit {
            while let Some(sample) = health.receive().expect("receive health") {
                if sample.process_name.as_str() != "lidar" {
                    continue;
                }
                let beat = Beat {
                    state: sample.run_state.get().expect("run state"),
                    detail: sample.detail.as_str().to_string(),
                    value: sample.detail_value,
                };
                if want(&beat) {
                    return (beat, start.elapsed());
                }
                last = Some(beat);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!("no matching lidar heartbeat within {limit:?}; last {last:?}");
    }

    /// Clouds received within `window` (after the first one, which may take a while).
    fn clouds(&self, first_within: Duration, window: Duration) -> usize {
        let clouds = self.context.subscriber(LIDAR_POINTS).expect("points");
        let deadline = Instant::now() + first_within;
        loop {
            if clouds.receive().expect("receive").is_some() {
                break;
            }
            assert!(
                Instant::now() < deadline,
                "no cloud within {first_within:?}"
            );
            let _ = clouds
                .listener()
                .timed_wait(|_| {}, Duration::from_millis(50));
        }
        let end = Instant::now() + window;
        let mut count = 0;
        while Instant::now() < end {
            while let Some(cloud) = clouds.receive().expect("receive") {
                assert!(cloud.meta.point_count > 1_000, "{:?}", cloud.meta);
                count += 1;
            }
            let _ = clouds
                .listener()
                .timed_wait(|_| {}, Duration::from_millis(50));
        }
        count
    }
}

#[test]
fn harvest_lidar_drives_the_fake_mid70_through_drops_silence_and_a_reboot() {
    let _watchdog = TestWatchdog::arm("livox lidar process", Duration::from_secs(180));
    let mut fake = Fake::start();
    let domain = unique_domain("livox");
    let port = fake.port.to_string();
    let lidar = Drained::spawn(
        &domain,
        &[
            "lidar",
            "--device",
            "livox",
            "--lidar-ip",
            "127.0.0.1",
            "--lidar-cmd-port",
            &port,
            "--host-ip",
            "127.0.0.1",
            "--host-cmd-port",
            "0",
            "--host-data-port",
            "0",
            "--integration-s",
            "0.2",
        ],
    );
    let watch = Watch {
        context: Context::new(domain.domain(), "livox-test").expect("node"),
    };

    // Five clouds a second (0.2 s windows of device time).
    let count = watch.clouds(Duration::from_secs(20), Duration::from_secs(3));
    assert!((12..=18).contains(&count), "{count} clouds in 3 s");
    watch.heartbeat(Duration::from_secs(5), |b| {
        b.state == ProcessRunState::Running && b.detail == "points"
    });

    fake.command("drop 25");
    watch.heartbeat(Duration::from_secs(10), |b| {
        b.detail == "lost_packets" && b.value == 25
    });

    fake.command("silent 5000");
    let (beat, reported_after) = watch.heartbeat(Duration::from_secs(10), |b| {
        b.state == ProcessRunState::Degraded
    });
    assert_eq!(beat.detail, "disconnected");
    eprintln!("silence reported after {reported_after:?}");
    let (_, back_after) = watch.heartbeat(Duration::from_secs(15), |b| {
        b.state == ProcessRunState::Running
    });
    eprintln!("running again {back_after:?} after the report");
    assert!(watch.clouds(Duration::from_secs(5), Duration::from_secs(1)) >= 3);

    fake.command("reboot 1500");
    watch.heartbeat(Duration::from_secs(10), |b| {
        b.state == ProcessRunState::Degraded
    });
    let (beat, _) = watch.heartbeat(Duration::from_secs(15), |b| {
        b.state == ProcessRunState::Running
    });
    // Neither the silence nor the reboot counts as lost packets.
    assert_eq!((beat.detail.as_str(), beat.value), ("lost_packets", 25));
    assert!(watch.clouds(Duration::from_secs(5), Duration::from_secs(1)) >= 3);

    let (status, _, stderr) = lidar.interrupt_and_wait(Duration::from_secs(10));
    assert!(status.success(), "harvest lidar failed:\n{stderr}");
    assert!(stderr.contains("livox sampling"), "{stderr}");
    assert!(stderr.contains("silent"), "{stderr}");
}
