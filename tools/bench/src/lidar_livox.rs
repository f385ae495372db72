//! `harvest bench lidar-livox`: the Livox Mid-70 driver end to end on loopback.
//!
//! The fake Mid-70 ([`harvest_sim::fake_mid70`], the SDK 1 protocol over UDP, 100,000 firings/s
//! of the simulator's rosette scan) runs in this process; `harvest lidar --device livox` runs as
//! its own process in a scratch domain; this process subscribes to `lidar/points` and to the
//! health channel. Measured:
//!
//! - for `--duration`: clouds, returns, lost packets (the driver's count, from its heartbeat,
//!   and the fake's packets sent against the scan time the clouds hold), the `harvest lidar`
//!   process's CPU time (user + system, `/proc/<pid>/stat`) per second of points, and the
//!   latency from the end of each window (`header.capture_ns`: the last firing's device time
//!   mapped to the stack clock, i.e. when its packet left the device) to the cloud's arrival at
//!   this subscriber of `lidar/points`;
//! - then the fake goes silent for `--silence` : the time until the process's heartbeat reports
//!   the device lost (`Degraded`), and, once the fake speaks again, the time until the next
//!   cloud arrives (reconnection, handshake, start sampling and one window).

use crate::driver_child::DriverChild;
use crate::stats::{LatencySummary, latency_histogram};
use harvest_hw::lidar::livox::command::BroadcastCode;
use harvest_ipc::catalogue::{LIDAR_POINTS, PROCESS_HEALTH};
use harvest_ipc::duration::parse_duration;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{Context, MonotonicClock, ScratchDomain};
use harvest_sim::fake_mid70::{FakeFault, FakeMid70, FakeMid70Config};
use serde::Serialize;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Options of `harvest bench lidar-livox`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchLidarLivoxArgs {
    /// How long to stream before the silence test.
    #[arg(long, value_parser = parse_duration, default_value = "60s")]
    pub duration: Duration,
    /// Integration window of the clouds, seconds.
    #[arg(long, default_value_t = 0.1)]
    pub integration_s: f64,
    /// How long the fake goes silent.
    #[arg(long, value_parser = parse_duration, default_value = "5s")]
    pub silence: Duration,
    /// Write the report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The `harvest` executable to run `harvest lidar` from (default: this one).
    #[arg(long)]
    pub harvest_exe: Option<PathBuf>,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum LidarLivoxBenchError {
    #[error("fake mid-70: {0}")]
    Fake(#[from] harvest_sim::fake_mid70::FakeMid70Error),
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    #[error("starting {exe}: {source}")]
    Spawn {
        exe: PathBuf,
        source: std::io::Error,
    },
    #[error("{0}")]
    Failed(String),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

harvest_ipc::from_ipc_errors!(LidarLivoxBenchError);

/// The figures.
#[derive(Debug, Clone, Serialize)]
pub struct LidarLivoxReport {
    pub tool: &'static str,
    pub duration_s: f64,
    pub integration_s: f64,
    pub clouds: u64,
    pub points: u64,
    pub points_per_s: f64,
    /// Scan time the clouds hold, seconds (firings received x 10 us).
    pub scan_time_s: f64,
    /// Packets the fake sent while measured.
    pub packets_sent: u64,
    /// Packets the scan time held accounts for (scan time / 0.96 ms).
    pub packets_in_clouds: u64,
    /// The driver's lost-packet count at the end (its heartbeat).
    pub lost_packets: u64,
    /// CPU seconds of the `harvest lidar` process per second of points.
    pub cpu_s_per_s: f64,
    /// End of window -> arrival at the `lidar/points` subscriber.
    pub latency: LatencySummary,
    /// Silence start -> heartbeat reporting the device lost.
    pub silence_reported_after_s: f64,
    /// Device speaking again -> next cloud received.
    pub reconnected_after_s: f64,
}

/// User + system CPU time of `pid`, seconds.
fn cpu_time_s(pid: u32) -> Result<f64, LidarLivoxBenchError> {
    crate::proc_cpu::cpu_time_s(pid).map_err(LidarLivoxBenchError::Failed)
}

/// Runs the benchmark and prints its report.
pub fn run_bench_lidar_livox(
    args: &BenchLidarLivoxArgs,
) -> Result<LidarLivoxReport, LidarLivoxBenchError> {
    if !(args.integration_s >= 0.01 && args.integration_s <= 1.0) {
        return Err(LidarLivoxBenchError::Failed(format!(
            "--integration-s {} outside 0.01..=1",
            args.integration_s
        )));
    }
    let code = BroadcastCode::parse("3GGDJ6K00100101")
        .map_err(|error| LidarLivoxBenchError::Failed(error.to_string()))?;
    let fake = FakeMid70::start(FakeMid70Config::loopback(code))?;
    let domain = ScratchDomain::new("blivox");
    let exe = match &args.harvest_exe {
        Some(path) => path.clone(),
        None => std::env::current_exe().map_err(|source| LidarLivoxBenchError::Spawn {
            exe: PathBuf::from("<current exe>"),
            source,
        })?,
    };
    let context = Context::new(&domain, "bench-lidar-livox")?;
    let clouds = context.subscriber_with_buffer(LIDAR_POINTS, 16)?;
    let health = context.subscriber(PROCESS_HEALTH)?;
    let port = fake.cmd_addr().port().to_string();
    let integration = args.integration_s.to_string();
    let child = Command::new(&exe)
        .args([
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
            &integration,
        ])
        .env("HARVEST_DOMAIN", domain.name())
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|source| LidarLivoxBenchError::Spawn {
            exe: exe.clone(),
            source,
        })?;
    let child = DriverChild(child);
    let pid = child.0.id();

    // Health: the lidar process's latest heartbeat.
    let mut last_beat: Option<(ProcessRunState, String, u64)> = None;
    let read_health =
        |last: &mut Option<(ProcessRunState, String, u64)>| -> Result<(), LidarLivoxBenchError> {
            while let Some(sample) = health.receive()? {
                if sample.process_name.as_str() == "lidar"
                    && let Ok(state) = sample.run_state.get()
                {
                    *last = Some((
                        state,
                        sample.detail.as_str().to_string(),
                        sample.detail_value,
                    ));
                }
            }
            Ok(())
        };

    // Wait for the stream to settle: the first few clouds.
    if !crate::settle::settled(&clouds, 5, Duration::from_secs(30))? {
        return Err(LidarLivoxBenchError::Failed(
            "no clouds from harvest lidar within 30 s".into(),
        ));
    }
    read_health(&mut last_beat)?;
    let lost_before = match &last_beat {
        Some((_, detail, value)) if detail == "lost_packets" => *value,
        _ => 0,
    };

    let cpu_start = cpu_time_s(pid)?;
    let sent_start = fake.stats().packets_sent;
    let start = Instant::now();
    let mut histogram =
        latency_histogram().map_err(|error| LidarLivoxBenchError::Failed(error.to_string()))?;
    let (mut cloud_count, mut points, mut scan_ns) = (0u64, 0u64, 0u64);
    while start.elapsed() < args.duration {
        while let Some(cloud) = clouds.receive()? {
            let now = MonotonicClock::read_ns();
            let _ = histogram.record(now.saturating_sub(cloud.header.capture_ns).max(1));
            cloud_count += 1;
            points += u64::from(cloud.meta.point_count);
            scan_ns += cloud.meta.integration_ns;
        }
        let left = args.duration.saturating_sub(start.elapsed());
        let _ = clouds
            .listener()
            .timed_wait(|_| {}, left.min(Duration::from_millis(500)));
    }
    let elapsed_s = start.elapsed().as_secs_f64();
    let cpu_s = cpu_time_s(pid)? - cpu_start;
    let packets_sent = fake.stats().packets_sent - sent_start;
    // The heartbeat after the run (twice a second).
    std::thread::sleep(Duration::from_millis(600));
    read_health(&mut last_beat)?;
    let lost_packets = match &last_beat {
        Some((_, detail, value)) if detail == "lost_packets" => value - lost_before,
        _ => 0,
    };

    // Silence: reported, then reconnected.
    while clouds.receive()?.is_some() {}
    fake.inject(FakeFault::Silent(args.silence));
    let silent_at = Instant::now();
    let reported_after = loop {
        read_health(&mut last_beat)?;
        if matches!(&last_beat, Some((ProcessRunState::Degraded, _, _))) {
            break silent_at.elapsed();
        }
        if silent_at.elapsed() > args.silence + Duration::from_secs(10) {
            return Err(LidarLivoxBenchError::Failed(
                "the silent device was never reported".into(),
            ));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let back_at = silent_at + args.silence;
    let reconnected_after = loop {
        let mut arrived = None;
        while clouds.receive()?.is_some() {
            arrived.get_or_insert(Instant::now());
        }
        if let Some(arrived) = arrived
            && arrived >= back_at
        {
            break arrived.duration_since(back_at);
        }
        if Instant::now() > back_at + Duration::from_secs(30) {
            return Err(LidarLivoxBenchError::Failed(
                "no cloud within 30 s of the device's return".into(),
            ));
        }
        let _ = clouds
            .listener()
            .timed_wait(|_| {}, Duration::from_millis(5));
    };
    drop(child);

    let report = LidarLivoxReport {
        tool: "harvest bench lidar-livox",
        duration_s: elapsed_s,
        integration_s: args.integration_s,
        clouds: cloud_count,
        points,
        points_per_s: points as f64 / elapsed_s,
        scan_time_s: scan_ns as f64 * 1e-9,
        packets_sent,
        packets_in_clouds: scan_ns / 960_000,
        lost_packets,
        cpu_s_per_s: cpu_s / elapsed_s,
        latency: LatencySummary::from_histogram(&histogram),
        silence_reported_after_s: reported_after.as_secs_f64(),
        reconnected_after_s: reconnected_after.as_secs_f64(),
    };
    print_report(&report);
    if let Some(path) = &args.json {
        crate::json_report::write_json_report(path, &report).map_err(|source| {
            LidarLivoxBenchError::Write {
                path: path.clone(),
                source,
            }
        })?;
    }
    Ok(report)
}

fn print_report(r: &LidarLivoxReport) {
    let ms = |ns: u64| ns as f64 / 1e6;
    println!(
        "harvest bench lidar-livox: {:.1} s at {} s windows",
        r.duration_s, r.integration_s
    );
    println!(
        "  clouds {}  returns {} ({:.0}/s)  scan time held {:.3} s",
        r.clouds, r.points, r.points_per_s, r.scan_time_s
    );
    println!(
        "  packets sent {}  in clouds {}  lost (driver) {}",
        r.packets_sent, r.packets_in_clouds, r.lost_packets
    );
    println!("  harvest lidar CPU {:.3} s per s of points", r.cpu_s_per_s);
    println!(
        "  window end -> lidar/points subscriber: p50 {:.2} ms  p99 {:.2} ms  max {:.2} ms ({} clouds)",
        ms(r.latency.p50_ns),
        ms(r.latency.p99_ns),
        ms(r.latency.max_ns),
        r.latency.samples
    );
    println!(
        "  silent device reported after {:.2} s; reconnected {:.2} s after it spoke again",
        r.silence_reported_after_s, r.reconnected_after_s
    );
}
