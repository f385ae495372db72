//! `harvest bench remote`: the remote link with several robots on one machine.
//!
//! Each robot is a scratch domain with `harvest remote` listening on its own loopback port and
//! a replay thread in this process feeding it as a camera and two arms would (frames at
//! `--camera-hz`, written in place, stamped with their capture time; arm states at 200 Hz);
//! robot 1 also runs `harvest executive`. The station is a separate process
//! (`harvest bench remote-station`, this same executable) connected to every robot, which
//! watches everything each robot sends (the camera included, each JPEG decoded as a screen
//! would), and sends commands to robot 1 at 10 Hz. Measured:
//!
//! - camera: capture (the frame's `capture_ns`, the robots' and the station's clocks are the
//!   same machine's `CLOCK_MONOTONIC`) -> JPEG received and decoded at the station; images
//!   and bytes a second per robot (everything the robot sends counted, not only the camera);
//! - command round trip: the station's query -> the executive's answer back at the station;
//! - the station's CPU (user + system, `/proc/self/stat`) per robot.

use crate::driver_child::DriverChild;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{ARM_STATE, CAMERA_RGBD};
use harvest_ipc::duration::parse_duration;
use harvest_ipc::payloads::ArmPhase;
use harvest_ipc::payloads::rgbd_frame::RGB_BYTES;
use harvest_ipc::{Context, MonotonicClock, ScratchDomain};
use harvest_operator::ControlToken;
use harvest_operator::token::write_token_file;
use harvest_remote_process::station_ctl::Station;
use harvest_remote_process::zenoh::Wait;
use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

use crate::scene_frame::SceneFrame;
use crate::stats::LatencySummary;

/// Options of `harvest bench remote`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchRemoteArgs {
    /// Robots (domains), each with its own `harvest remote`.
    #[arg(long, default_value_t = 4)]
    pub robots: usize,
    /// How long the station measures.
    #[arg(long, value_parser = parse_duration, default_value = "30s")]
    pub duration: Duration,
    /// Camera frames a second each robot's replay publishes.
    #[arg(long, default_value_t = 30.0)]
    pub camera_hz: f64,
    /// First loopback port (robot i listens on port + i).
    #[arg(long, default_value_t = 17447)]
    pub port: u16,
    /// Write the report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Options of the station process (`harvest bench remote-station`, started by the bench).
#[derive(Debug, Clone, clap::Args)]
pub struct BenchRemoteStationArgs {
    #[arg(long)]
    pub robots: usize,
    #[arg(long)]
    pub port: u16,
    #[arg(long, value_parser = parse_duration)]
    pub duration: Duration,
    /// Robot 1's control token.
    #[arg(long)]
    pub token: String,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum RemoteBenchError {
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    #[error(transparent)]
    Remote(#[from] harvest_remote_process::RemoteError),
    #[error("{0}")]
    Failed(String),
}

harvest_ipc::from_ipc_errors!(RemoteBenchError);

/// What the station measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StationReport {
    pub robots: usize,
    pub duration_s: f64,
    /// Camera images received per robot.
    pub images_per_robot: Vec<u64>,
    /// Bytes received per robot per second (everything under its key).
    pub bytes_per_s_per_robot: Vec<f64>,
    pub camera_latency: LatencySummary,
    pub command_round_trip: LatencySummary,
    pub commands_answered: u64,
    pub commands_unanswered: u64,
    /// Station CPU seconds per second, per robot (1.0 = one core).
    pub cpu_per_robot: f64,
    pub cpu_total: f64,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct RemoteBenchReport {
    pub tool: &'static str,
    pub camera_hz: f64,
    pub station: StationReport,
    /// `harvest remote`'s CPU seconds per second, per robot.
    pub bridge_cpu: Vec<f64>,
}

fn histogram() -> Result<Histogram<u64>, RemoteBenchError> {
    Histogram::new_with_bounds(1_000, 60_000_000_000, 3)
        .map_err(|error| RemoteBenchError::Failed(error.to_string()))
}

/// User + system CPU seconds of this process.
fn own_cpu_s() -> f64 {
    cpu_s(std::process::id())
}

/// User + system CPU seconds of `pid` (0 once it is gone).
fn cpu_s(pid: u32) -> f64 {
    crate::proc_cpu::cpu_time_s(pid).unwrap_or(0.0)
}

/// The station: runs in its own process; prints its [`StationReport`] as JSON.
pub fn run_bench_remote_station(args: &BenchRemoteStationArgs) -> Result<(), RemoteBenchError> {
    use std::sync::Mutex;
    let link = harvest_remote_process::link_session::LinkArgs {
        link_file: None,
        listen: Vec::new(),
        connect: (0..args.robots)
            .map(|i| format!("tcp/127.0.0.1:{}", usize::from(args.port) + i))
            .collect(),
    };
    let robot1 = harvest_remote::RobotName::parse("bench1")
        .map_err(|error| RemoteBenchError::Failed(error.to_string()))?;
    let station = Station::connect(robot1, &link, Duration::from_secs(20))?
        .ok_or_else(|| RemoteBenchError::Failed("robot bench1 not seen within 20 s".to_owned()))?;
    let token = ControlToken::parse(&args.token, "--token")
        .map_err(|error| RemoteBenchError::Failed(error.to_string()))?;
    struct Tally {
        images: Vec<u64>,
        bytes: Vec<u64>,
        latency: Histogram<u64>,
    }
    let tally = Arc::new(Mutex::new(Tally {
        images: vec![0; args.robots],
        bytes: vec![0; args.robots],
        latency: histogram()?,
    }));
    let on_sample = Arc::clone(&tally);
    let subscriber = station
        .session()
        .declare_subscriber("harvest/v1/**")
        .callback(move |sample| {
            let Some((robot, suffix)) = harvest_remote::keys::split_key(sample.key_expr().as_str())
            else {
                return;
            };
            let Some(index) = robot
                .as_str()
                .strip_prefix("bench")
                .and_then(|n| n.parse::<usize>().ok())
                .and_then(|n| n.checked_sub(1))
            else {
                return;
            };
            let payload = sample.payload().to_bytes();
            let mut latency_ns = None;
            if suffix == "camera/jpeg" {
                // The screen: decode the image, then take the time.
                let decoded =
                    image::load_from_memory_with_format(&payload, image::ImageFormat::Jpeg).is_ok();
                let attachment = sample.attachment().and_then(|a| {
                    serde_json::from_slice::<harvest_remote::camera_image::CameraAttachment>(
                        &a.to_bytes(),
                    )
                    .ok()
                });
                if decoded && let Some(attachment) = attachment {
                    latency_ns =
                        Some(MonotonicClock::read_ns().saturating_sub(attachment.capture_ns));
                }
            }
            let mut tally = on_sample.lock().unwrap_or_else(|p| p.into_inner());
            if let Some(bytes) = tally.bytes.get_mut(index) {
                *bytes += payload.len() as u64;
            }
            if let Some(latency) = latency_ns {
                if let Some(images) = tally.images.get_mut(index) {
                    *images += 1;
                }
                let _ = tally.latency.record(latency.max(1));
            }
        })
        .wait()
        .map_err(|error| RemoteBenchError::Failed(error.to_string()))?;
    // Let every robot's camera match and its first images arrive before measuring.
    std::thread::sleep(Duration::from_secs(3));
    let cpu_start = own_cpu_s();
    {
        let mut tally = tally.lock().unwrap_or_else(|p| p.into_inner());
        tally.images.iter_mut().for_each(|n| *n = 0);
        tally.bytes.iter_mut().for_each(|n| *n = 0);
        tally.latency.reset();
    }
    let start = Instant::now();
    let mut round_trip = histogram()?;
    let (mut answered, mut unanswered) = (0u64, 0u64);
    while start.elapsed() < args.duration {
        let sent = Instant::now();
        match station.send(
            harvest_operator::Command::Heartbeat,
            Some(&token),
            Duration::from_secs(2),
        )? {
            Some(_) => {
                answered += 1;
                let _ = round_trip.record((sent.elapsed().as_nanos() as u64).max(1));
            }
            None => unanswered += 1,
        }
        std::thread::sleep(Duration::from_millis(100).saturating_sub(sent.elapsed()));
    }
    let elapsed_s = start.elapsed().as_secs_f64();
    let cpu_total = (own_cpu_s() - cpu_start) / elapsed_s;
    drop(subscriber);
    let tally = tally.lock().unwrap_or_else(|p| p.into_inner());
    let report = StationReport {
        robots: args.robots,
        duration_s: elapsed_s,
        images_per_robot: tally.images.clone(),
        bytes_per_s_per_robot: tally.bytes.iter().map(|b| *b as f64 / elapsed_s).collect(),
        camera_latency: LatencySummary::from_histogram(&tally.latency),
        command_round_trip: LatencySummary::from_histogram(&round_trip),
        commands_answered: answered,
        commands_unanswered: unanswered,
        cpu_per_robot: cpu_total / args.robots.max(1) as f64,
        cpu_total,
    };
    println!(
        "{}",
        serde_json::to_string(&report).map_err(|e| RemoteBenchError::Failed(e.to_string()))?
    );
    Ok(())
}

fn spawn(exe: &PathBuf, domain: &str, args: &[&str]) -> Result<DriverChild, RemoteBenchError> {
    Command::new(exe)
        .args(args)
        .env("HARVEST_DOMAIN", domain)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .map(DriverChild)
        .map_err(|error| RemoteBenchError::Failed(format!("starting {}: {error}", exe.display())))
}

/// Runs the benchmark.
pub fn run_bench_remote(args: &BenchRemoteArgs) -> Result<RemoteBenchReport, RemoteBenchError> {
    if args.robots == 0 || args.robots > 16 {
        return Err(RemoteBenchError::Failed(
            "--robots must be 1..=16".to_owned(),
        ));
    }
    let exe = std::env::current_exe().map_err(|e| RemoteBenchError::Failed(e.to_string()))?;
    let token = ControlToken::generate().map_err(|e| RemoteBenchError::Failed(e.to_string()))?;
    let scratch = std::env::temp_dir().join(format!("harvest-bench-remote-{}", std::process::id()));
    let token_file = scratch.join("bench1.token");
    write_token_file(&token_file, &token).map_err(|e| RemoteBenchError::Failed(e.to_string()))?;
    let domains: Vec<ScratchDomain> = (0..args.robots)
        .map(|_| ScratchDomain::new("bremote"))
        .collect();
    let mut children = Vec::new();
    let mut bridges = Vec::new();
    let token_path = token_file.display().to_string();
    for (i, domain) in domains.iter().enumerate() {
        if i == 0 {
            children.push(spawn(
                &exe,
                domain.name(),
                &[
                    "executive",
                    "--platform",
                    "none",
                    "--initial-mode",
                    "idle",
                    "--token-file",
                    &token_path,
                ],
            )?);
        }
        let robot = format!("bench{}", i + 1);
        let listen = format!("tcp/127.0.0.1:{}", usize::from(args.port) + i);
        bridges.push(spawn(
            &exe,
            domain.name(),
            &["remote", "--robot", &robot, "--listen", &listen],
        )?);
    }
    // The replay threads: camera frames and arm states into each robot's domain. The frames
    // are the simulator's render of the default scenario (a blank frame would flatter JPEG's
    // size and time), with a moving stripe so that each image differs, as a camera's do.
    let scene =
        SceneFrame::render("default").map_err(|e| RemoteBenchError::Failed(e.to_string()))?;
    if scene.rgb.len() != RGB_BYTES {
        return Err(RemoteBenchError::Failed(format!(
            "the default scenario renders {}x{}, camera/rgbd holds 1920x1080",
            scene.width_px, scene.height_px
        )));
    }
    let scene = Arc::new(scene.rgb);
    let running = Arc::new(AtomicBool::new(true));
    let mut replays = Vec::new();
    for domain in &domains {
        let domain = domain.domain().clone();
        let running = Arc::clone(&running);
        let scene = Arc::clone(&scene);
        let frame_period = Duration::from_secs_f64(1.0 / args.camera_hz.clamp(1.0, 60.0));
        replays.push(std::thread::spawn(
            move || -> Result<(), RemoteBenchError> {
                let context = Context::new(&domain, "bench-replay")?;
                let mut frames = context.publisher(CAMERA_RGBD)?;
                let mut arms = [
                    context.publisher(ARM_STATE[0])?,
                    context.publisher(ARM_STATE[1])?,
                ];
                let mut next_frame = Instant::now();
                let mut n = 0u64;
                while running.load(Ordering::SeqCst) {
                    let now_ns = MonotonicClock::read_ns();
                    for (i, arm) in arms.iter_mut().enumerate() {
                        arm.publish_with(now_ns, |state| {
                            state.arm_id = i as u8 + 1;
                            state.phase.set(ArmPhase::Idle);
                        })?;
                    }
                    if Instant::now() >= next_frame {
                        next_frame += frame_period;
                        n += 1;
                        frames.publish_with(now_ns, |frame| {
                            frame.rgb.copy_from_slice(&scene);
                            let row = (n as usize * 8) % 1000;
                            for px in
                                frame.rgb[row * 1920 * 3..(row + 8) * 1920 * 3].chunks_exact_mut(3)
                            {
                                px[0] = (n % 255) as u8;
                                px[1] = 200;
                            }
                        })?;
                    }
                    std::thread::sleep(Duration::from_millis(5));
                }
                Ok(())
            },
        ));
    }
    let bridge_cpu_start: Vec<f64> = bridges.iter().map(|b| cpu_s(b.0.id())).collect();
    let started = Instant::now();
    let station = Command::new(&exe)
        .args([
            "bench",
            "remote-station",
            "--robots",
            &args.robots.to_string(),
            "--port",
            &args.port.to_string(),
            "--duration",
            &format!("{}ms", args.duration.as_millis()),
            "--token",
            token.as_str(),
        ])
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| RemoteBenchError::Failed(format!("station: {e}")))?;
    let elapsed_s = started.elapsed().as_secs_f64();
    let bridge_cpu: Vec<f64> = bridges
        .iter()
        .zip(&bridge_cpu_start)
        .map(|(b, start)| (cpu_s(b.0.id()) - start) / elapsed_s)
        .collect();
    running.store(false, Ordering::SeqCst);
    for replay in replays {
        let _ = replay.join();
    }
    drop(bridges);
    drop(children);
    let _ = std::fs::remove_dir_all(&scratch);
    if !station.status.success() {
        return Err(RemoteBenchError::Failed(format!(
            "the station failed: {}",
            String::from_utf8_lossy(&station.stdout)
        )));
    }
    let station: StationReport = serde_json::from_slice(&station.stdout)
        .map_err(|e| RemoteBenchError::Failed(format!("station report: {e}")))?;
    let report = RemoteBenchReport {
        tool: "harvest bench remote",
        camera_hz: args.camera_hz,
        station,
        bridge_cpu,
    };
    print_report(&report);
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_vec_pretty(&report).unwrap_or_default())
            .map_err(|e| RemoteBenchError::Failed(format!("{}: {e}", path.display())))?;
    }
    Ok(report)
}

fn ms(ns: u64) -> f64 {
    ns as f64 / 1e6
}

fn print_report(report: &RemoteBenchReport) {
    let s = &report.station;
    println!(
        "harvest bench remote: {} robots, {:.0} s, camera replayed at {} Hz",
        s.robots, s.duration_s, report.camera_hz
    );
    println!(
        "camera capture -> decoded at the station: p50 {:.1} ms, p99 {:.1} ms, max {:.1} ms ({} images)",
        ms(s.camera_latency.p50_ns),
        ms(s.camera_latency.p99_ns),
        ms(s.camera_latency.max_ns),
        s.camera_latency.samples
    );
    for (i, (images, bytes)) in s
        .images_per_robot
        .iter()
        .zip(&s.bytes_per_s_per_robot)
        .enumerate()
    {
        println!(
            "robot bench{}: {:.2} images/s, {:.1} kB/s on the link, harvest remote CPU {:.1} %",
            i + 1,
            *images as f64 / s.duration_s,
            bytes / 1e3,
            report.bridge_cpu.get(i).copied().unwrap_or(0.0) * 100.0
        );
    }
    println!(
        "command round trip (station -> executive -> station): p50 {:.1} ms, p99 {:.1} ms ({} answered, {} unanswered)",
        ms(s.command_round_trip.p50_ns),
        ms(s.command_round_trip.p99_ns),
        s.commands_answered,
        s.commands_unanswered
    );
    println!(
        "station CPU: {:.1} % in all, {:.2} % per robot",
        s.cpu_total * 100.0,
        s.cpu_per_robot * 100.0
    );
}
