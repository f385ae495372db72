//! `harvest bench console`: what the operator console costs and how fast it is, against a
//! running stack (sim, camera, both arms, executive, console; in a domain of its own):
//!
//! - **CPU per viewer**: the console's CPU over a window with 0, a quarter of and all the
//!   push viewers (clients that take every message), measured side by side in one run; the
//!   cost of one viewer is the slope;
//! - **capture to the browser's image**: Debian's Chromium shows the page; the page's own
//!   figure (the camera's capture stamp to the decoded image, on the stack clock estimated
//!   over the push connection), p50 and p99, on a quiet console and under load (the viewers
//!   and the half-open connections);
//! - **e-stop click to both arms stopped** under load: the page's button clicked in Chromium,
//!   to the first `armN/state` saying `Stopped` (stamped in the arm's tick that brakes; the page
//!   notes the click on the stack clock); each click released and harvesting restarted before
//!   the next; median;
//! - **memory**: the console's private resident memory (`RssAnon`) sampled over a run with
//!   viewers coming and going.

pub mod chromium;
pub mod http_client;
pub mod live;
pub mod load;

use std::net::Ipv4Addr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{ARM_STATE, EMERGENCY_STOP, PROCESS_HEALTH};
use harvest_ipc::payloads::{ArmPhase, EmergencyStop};
use harvest_ipc::{Context, Domain, Subscriber};
use serde::Serialize;
use serde_json::{Value, json};

use crate::error::BenchError;
use crate::pipeline::stack::Stack;
use crate::proc_cpu::cpu_time_s;
use crate::stats::percentile;
use chromium::Chromium;
use load::{HalfOpen, Viewers};

/// `harvest bench console` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchConsoleArgs {
    /// Push viewers at full load (clients that take every message).
    #[arg(long, default_value_t = 20)]
    pub viewers: usize,
    /// Half-open connections at full load (a request head that never ends; renewed as the
    /// console closes them).
    #[arg(long, default_value_t = 50)]
    pub half_open: usize,
    /// CPU window per number of viewers, s.
    #[arg(long, default_value_t = 10.0)]
    pub cpu_window_s: f64,
    /// Window of capture-to-image latencies in Chromium per condition, s.
    #[arg(long, default_value_t = 20.0)]
    pub latency_window_s: f64,
    /// E-stop clicks under load.
    #[arg(long, default_value_t = 5)]
    pub estop_clicks: usize,
    /// Memory run with viewers coming and going, s (0: none).
    #[arg(long, default_value_t = 600.0)]
    pub memory_run_s: f64,
    /// The simulated camera's rate, Hz.
    #[arg(long, default_value_t = 15.0)]
    pub camera_rate_hz: f64,
    /// Chromium.
    #[arg(long, default_value = "/usr/bin/chromium")]
    pub chromium: PathBuf,
    /// The `harvest` executable that runs the stack (default: this one).
    #[arg(long)]
    pub exe: Option<PathBuf>,
    /// Also write the report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Why the benchmark failed.
#[derive(Debug, thiserror::Error)]
pub enum ConsoleBenchError {
    /// A step failed; the message says which.
    #[error("console benchmark: {0}")]
    Failed(String),
    /// The stack.
    #[error(transparent)]
    Bench(#[from] BenchError),
    /// The transport.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(ConsoleBenchError);

fn failed(message: impl Into<String>) -> ConsoleBenchError {
    ConsoleBenchError::Failed(message.into())
}

/// The console's CPU with a number of viewers.
#[derive(Debug, Clone, Serialize)]
pub struct CpuPoint {
    pub viewers: usize,
    /// Percent of one core.
    pub cpu_percent: f64,
    /// Views each viewer received per second (mean).
    pub views_per_viewer_hz: f64,
}

/// Capture-to-image latencies in Chromium under one condition.
#[derive(Debug, Clone, Serialize)]
pub struct LatencyFigures {
    pub condition: String,
    pub views: usize,
    pub p50_ms: f64,
    pub p99_ms: f64,
}

/// The console's memory over the run with viewers coming and going.
#[derive(Debug, Clone, Serialize)]
pub struct MemoryFigures {
    pub duration_s: f64,
    pub samples: usize,
    /// `RssAnon` after the warm-up, at the end and its maximum, KiB.
    pub first_kib: u64,
    pub last_kib: u64,
    pub max_kib: u64,
    /// Push connections opened and closed during the run.
    pub viewers_opened: u64,
}

/// One e-stop click, timed twice: from the click (the page's estimate of the stack's clock,
/// good to `clock_uncertainty_ms`) and from the executive's stop (the stack's clock alone).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct EstopClick {
    /// The click to arm 1 and arm 2 reporting `Stopped`, ms.
    pub click_to_stopped_ms: [f64; 2],
    /// The click to the executive's stop (`safety/emergency_stop` engaged, its stamp), ms.
    pub click_to_engaged_ms: f64,
    /// The executive's stop to arm 1 and arm 2 reporting `Stopped`, ms.
    pub engaged_to_stopped_ms: [f64; 2],
    /// Half the page's fastest clock round trip: how far the page's estimate of the stack's
    /// clock can be off, ms.
    pub clock_uncertainty_ms: f64,
}

/// The benchmark's figures.
#[derive(Debug, Clone, Serialize)]
pub struct ConsoleReport {
    pub cpu: Vec<CpuPoint>,
    /// Slope of the console's CPU per viewer, percent of one core.
    pub cpu_per_viewer_percent: f64,
    pub latency: Vec<LatencyFigures>,
    /// Each e-stop click.
    pub estop_clicks: Vec<EstopClick>,
    /// The median of the later arm of each click, click to stopped, ms.
    pub estop_both_stopped_p50_ms: f64,
    /// The median of the later arm of each click, the executive's stop to stopped (the stack's
    /// clock only), ms.
    pub estop_engaged_to_both_stopped_p50_ms: f64,
    pub memory: Option<MemoryFigures>,
    pub viewers: usize,
    pub half_open: usize,
}

impl ConsoleReport {
    /// The report as text.
    pub fn render(&self) -> String {
        let mut text = String::from("console benchmark\n");
        for point in &self.cpu {
            text.push_str(&format!(
                "  CPU with {:>2} viewers: {:5.1} % of one core ({:.1} views/s each)\n",
                point.viewers, point.cpu_percent, point.views_per_viewer_hz
            ));
        }
        text.push_str(&format!(
            "  CPU per viewer: {:.2} % of one core\n",
            self.cpu_per_viewer_percent
        ));
        for latency in &self.latency {
            text.push_str(&format!(
                "  capture to image in Chromium, {}: p50 {:.1} ms, p99 {:.1} ms ({} views)\n",
                latency.condition, latency.p50_ms, latency.p99_ms, latency.views
            ));
        }
        for (k, click) in self.estop_clicks.iter().enumerate() {
            let [arm1, arm2] = click.click_to_stopped_ms;
            let [stack1, stack2] = click.engaged_to_stopped_ms;
            text.push_str(&format!(
                "  e-stop click {}: to stopped arm 1 {arm1:.1} ms, arm 2 {arm2:.1} ms (to the executive's stop {:.1} ms, +-{:.1} ms; from it to stopped {stack1:.1} / {stack2:.1} ms)\n",
                k + 1,
                click.click_to_engaged_ms,
                click.clock_uncertainty_ms,
            ));
        }
        text.push_str(&format!(
            "  e-stop click to both arms stopped, p50: {:.1} ms; the executive's stop to both stopped, p50: {:.1} ms ({} viewers, {} half-open)\n",
            self.estop_both_stopped_p50_ms,
            self.estop_engaged_to_both_stopped_p50_ms,
            self.viewers,
            self.half_open
        ));
        if let Some(memory) = &self.memory {
            text.push_str(&format!(
                "  memory over {:.0} s ({} push connections opened): RssAnon {} KiB after warm-up, {} KiB at the end, {} KiB max\n",
                memory.duration_s, memory.viewers_opened, memory.first_kib, memory.last_kib, memory.max_kib
            ));
        }
        text
    }
}

/// The launch file of the stack a console is measured on (and tested under load on): the
/// simulator at `camera_rate_hz`, the camera, both arms, the executive harvesting without a
/// platform, and the console on `127.0.0.1:port` admitting `max_watchers` watchers; no
/// perception (the console's cost is measured, not detection's).
pub fn watched_stack_launch(port: u16, camera_rate_hz: f64, max_watchers: usize) -> String {
    format!(
        r#"# harvest bench console: the stack the console watches (no perception: the console's cost
# is measured, not detection's).
[stack]
startup_grace_ms = 15000
[[process]]
name = "sim"
command = "sim"
args = ["--scenario", "default", "--seed", "1", "--camera-rate-hz", "{rate}"]
[[process]]
name = "camera"
command = "camera"
[[process]]
name = "arm1"
command = "arm"
args = ["--id", "1"]
[[process]]
name = "arm2"
command = "arm"
args = ["--id", "2"]
[[process]]
name = "executive"
command = "executive"
args = ["--platform", "none", "--initial-mode", "harvesting"]
[[process]]
name = "console"
command = "console"
args = ["--listen", "127.0.0.1:{port}", "--max-watchers", "{watchers}"]
"#,
        rate = camera_rate_hz,
        watchers = max_watchers,
    )
}

fn wait_for(
    what: &str,
    limit: Duration,
    mut check: impl FnMut() -> bool,
) -> Result<(), ConsoleBenchError> {
    let deadline = Instant::now() + limit;
    while !check() {
        if Instant::now() > deadline {
            return Err(failed(format!("{what} not seen within {limit:?}")));
        }
        // Not a hot path: waiting for a stack to come up.
        std::thread::sleep(Duration::from_millis(100));
    }
    Ok(())
}

fn console_pid(health: &Subscriber<harvest_ipc::payloads::ProcessHealth>) -> Option<u32> {
    let mut pid = None;
    while let Ok(Some(beat)) = health.receive() {
        if beat.process_name.as_str() == "console" {
            pid = Some(beat.pid);
        }
    }
    pid
}

/// The console's CPU share over `window`, percent of one core.
fn cpu_percent(pid: u32, window: Duration) -> Result<f64, ConsoleBenchError> {
    let before = cpu_time_s(pid).map_err(failed)?;
    let started = Instant::now();
    std::thread::sleep(window);
    let after = cpu_time_s(pid).map_err(failed)?;
    Ok((after - before) / started.elapsed().as_secs_f64() * 100.0)
}

/// The page's capture-to-image latencies over `window`.
fn page_latencies(
    page: &mut Chromium,
    condition: &str,
    window: Duration,
) -> Result<LatencyFigures, ConsoleBenchError> {
    page.evaluate("window.consoleStats.latenciesMs = []; true")
        .map_err(failed)?;
    std::thread::sleep(window);
    let values = page
        .evaluate("window.consoleStats.latenciesMs")
        .map_err(failed)?;
    let mut values: Vec<f64> = values
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    Ok(LatencyFigures {
        condition: condition.to_owned(),
        views: values.len(),
        p50_ms: percentile(&mut values, 0.5),
        p99_ms: percentile(&mut values, 0.99),
    })
}

fn post_command(port: u16, token: &str, command: &str) -> Result<Value, ConsoleBenchError> {
    let body = json!({"token": token, "session": 77, "command": {"command": command}}).to_string();
    let (_, answer) =
        http_client::request(port, "POST", "/api/command", Some(&body)).map_err(failed)?;
    serde_json::from_slice(&answer).map_err(|e| failed(format!("answer to {command}: {e}")))
}

/// Whether each arm last said it was stopped, and the first stopped state's stamp since the
/// watch was reset.
struct ArmWatch {
    states: [Subscriber<harvest_ipc::payloads::ArmState>; 2],
    stopped: [Option<bool>; 2],
    stopped_ns: [Option<u64>; 2],
    /// The executive's stop, and when it first said engaged since the watch was reset.
    stop: Subscriber<EmergencyStop>,
    engaged: bool,
    engaged_ns: Option<u64>,
}

impl ArmWatch {
    fn update(&mut self) {
        while let Ok(Some(stop)) = self.stop.receive() {
            self.engaged = stop.engaged != 0;
            if self.engaged && self.engaged_ns.is_none() {
                self.engaged_ns = Some(stop.header.capture_ns);
            }
        }
        for (i, subscriber) in self.states.iter().enumerate() {
            while let Ok(Some(state)) = subscriber.receive() {
                let stopped = state.phase == ArmPhase::Stopped;
                self.stopped[i] = Some(stopped);
                if stopped && self.stopped_ns[i].is_none() {
                    self.stopped_ns[i] = Some(state.header.capture_ns);
                }
            }
        }
    }
}

/// One e-stop click in the page and the time to each arm's first held command, ms.
fn estop_click(
    page: &mut Chromium,
    arms: &mut ArmWatch,
    port: u16,
    token: &str,
) -> Result<EstopClick, ConsoleBenchError> {
    // Released and harvesting again, neither arm stopped, before the click.
    wait_for(
        "the stop released and both arms running before the click",
        Duration::from_secs(30),
        || {
            arms.update();
            !arms.engaged && arms.stopped == [Some(false), Some(false)]
        },
    )?;
    arms.stopped_ns = [None, None];
    arms.engaged_ns = None;
    let click_ns = page
        .evaluate(
            "window.consoleStats.estopClickNs = null; document.getElementById('btn-estop').click(); window.consoleStats.estopClickNs",
        )
        .map_err(failed)?
        .as_f64()
        .ok_or_else(|| failed("the page has no clock estimate yet"))?;
    wait_for(
        "both arms stopped after the click",
        Duration::from_secs(10),
        || {
            arms.update();
            arms.stopped_ns.iter().all(Option::is_some)
        },
    )?;
    let stopped_ns = arms.stopped_ns.map(|ns| ns.unwrap_or(0) as f64);
    let engaged_ns =
        arms.engaged_ns
            .ok_or_else(|| failed("the arms stopped without the executive's stop"))? as f64;
    let best_rtt_ms = page
        .evaluate("state.bestRttMs")
        .map_err(failed)?
        .as_f64()
        .ok_or_else(|| failed("the page has no clock round trip yet"))?;
    let click = EstopClick {
        click_to_stopped_ms: stopped_ns.map(|ns| (ns - click_ns) / 1e6),
        click_to_engaged_ms: (engaged_ns - click_ns) / 1e6,
        engaged_to_stopped_ms: stopped_ns.map(|ns| (ns - engaged_ns) / 1e6),
        clock_uncertainty_ms: best_rtt_ms / 2.0,
    };
    let released = post_command(port, token, "release")?;
    if released["accepted"] != true {
        return Err(failed(format!("release refused: {released}")));
    }
    let started = post_command(port, token, "start")?;
    if started["accepted"] != true {
        return Err(failed(format!("start refused: {started}")));
    }
    Ok(click)
}

/// Runs the benchmark.
pub fn run_bench_console(args: &BenchConsoleArgs) -> Result<ConsoleReport, ConsoleBenchError> {
    let exe = match &args.exe {
        Some(exe) => exe.clone(),
        None => std::env::current_exe().map_err(|e| failed(format!("current exe: {e}")))?,
    };
    let domain = Domain::new(&format!("bench-console-{}", std::process::id()))
        .map_err(|e| failed(e.to_string()))?;
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map_err(|e| failed(e.to_string()))?
        .port();
    let launch = std::env::temp_dir().join(format!("harvest-bench-console-{}.toml", domain.name()));
    std::fs::write(
        &launch,
        watched_stack_launch(port, args.camera_rate_hz, args.viewers + 8),
    )
    .map_err(|e| failed(format!("{}: {e}", launch.display())))?;
    let run_for = Duration::from_secs_f64(
        args.memory_run_s + 4.0 * args.cpu_window_s + 3.0 * args.latency_window_s + 300.0,
    );
    // The launch file stays until the stack has stopped: the supervisor reads it after it starts
    // (and again on a restart).
    let outcome = Stack::start(&exe, &domain, Some(&launch), run_for, true).map(|mut stack| {
        let report = measure(args, &domain, port, &mut stack);
        (report, stack.stop())
    });
    let _ = std::fs::remove_file(&launch);
    let (report, stopped) = outcome?;
    let report = report?;
    stopped?;
    if let Some(path) = &args.json {
        crate::json_report::write_json_report(path, &report)
            .map_err(|e| failed(format!("{}: {e}", path.display())))?;
    }
    Ok(report)
}

fn measure(
    args: &BenchConsoleArgs,
    domain: &Domain,
    port: u16,
    stack: &mut Stack,
) -> Result<ConsoleReport, ConsoleBenchError> {
    wait_for(
        "the console serving both arms and a camera view",
        Duration::from_secs(120),
        || {
            http_client::get_json(port, "/api/status").is_some_and(|s| {
                s["mode"]["name"] == "harvesting"
                    && s["arms"][0].is_object()
                    && s["arms"][1].is_object()
                    && s["view"].is_object()
            })
        },
    )?;
    stack.check_running()?;
    let token_path = harvest_operator::token::token_path(domain.name());
    let token = harvest_operator::token::read_token_file(&token_path)
        .map_err(|e| failed(format!("{}: {e}", token_path.display())))?
        .as_str()
        .to_owned();
    let context = Context::new(domain, "bench-console")?;
    let health = context.subscriber_with_buffer(PROCESS_HEALTH, 256)?;
    let mut pid = None;
    wait_for("the console's heartbeat", Duration::from_secs(10), || {
        pid = pid.or(console_pid(&health));
        pid.is_some()
    })?;
    let pid = pid.ok_or_else(|| failed("no console pid"))?;
    let mut arms = ArmWatch {
        states: [
            context.subscriber_with_buffer(ARM_STATE[0], 256)?,
            context.subscriber_with_buffer(ARM_STATE[1], 256)?,
        ],
        stopped: [None, None],
        stopped_ns: [None, None],
        stop: context.subscriber(EMERGENCY_STOP)?,
        engaged: false,
        engaged_ns: None,
    };
    let window = Duration::from_secs_f64(args.cpu_window_s);

    // CPU with 0, a quarter of and all the viewers, side by side.
    let mut cpu = Vec::new();
    let counts = [0, args.viewers / 4, args.viewers];
    for &count in &counts {
        let viewers = Viewers::open(port, count).map_err(failed)?;
        std::thread::sleep(Duration::from_secs(2));
        let views_before = viewers.views();
        let cpu_percent = cpu_percent(pid, window)?;
        let views = viewers.views() - views_before;
        cpu.push(CpuPoint {
            viewers: count,
            cpu_percent,
            views_per_viewer_hz: if count == 0 {
                0.0
            } else {
                views as f64 / count as f64 / window.as_secs_f64()
            },
        });
        viewers.close();
        stack.check_running()?;
    }
    let cpu_per_viewer_percent = match (cpu.first(), cpu.last()) {
        (Some(zero), Some(full)) if full.viewers > 0 => {
            (full.cpu_percent - zero.cpu_percent) / full.viewers as f64
        }
        _ => f64::NAN,
    };

    // Chromium: quiet, then under load.
    let mut page =
        Chromium::start(&args.chromium, &format!("http://127.0.0.1:{port}/")).map_err(failed)?;
    wait_for(
        "ten views shown in Chromium",
        Duration::from_secs(60),
        || {
            page.evaluate(
                "window.consoleStats.views >= 10 && window.consoleStats.latenciesMs.length > 0",
            )
            .is_ok_and(|v| v == true)
        },
    )?;
    let latency_window = Duration::from_secs_f64(args.latency_window_s);
    let mut latency = vec![page_latencies(&mut page, "quiet console", latency_window)?];
    let viewers = Viewers::open(port, args.viewers).map_err(failed)?;
    let half_open = HalfOpen::start(port, args.half_open);
    std::thread::sleep(Duration::from_secs(3));
    latency.push(page_latencies(
        &mut page,
        &format!("{} viewers + {} half-open", args.viewers, args.half_open),
        latency_window,
    )?);
    let mut estop_clicks = Vec::new();
    for _ in 0..args.estop_clicks {
        estop_clicks.push(estop_click(&mut page, &mut arms, port, &token)?);
        stack.check_running()?;
    }
    let later_arm_p50 = |times: fn(&EstopClick) -> [f64; 2]| {
        let mut later: Vec<f64> = estop_clicks
            .iter()
            .map(|click| {
                let [arm1, arm2] = times(click);
                arm1.max(arm2)
            })
            .collect();
        percentile(&mut later, 0.5)
    };
    let estop_both_stopped_p50_ms = later_arm_p50(|click| click.click_to_stopped_ms);
    let estop_engaged_to_both_stopped_p50_ms = later_arm_p50(|click| click.engaged_to_stopped_ms);
    half_open.stop();
    viewers.close();

    let memory = if args.memory_run_s > 0.0 {
        Some(memory_run(pid, port, args, stack)?)
    } else {
        None
    };
    drop(page);
    Ok(ConsoleReport {
        cpu,
        cpu_per_viewer_percent,
        latency,
        estop_clicks,
        estop_both_stopped_p50_ms,
        estop_engaged_to_both_stopped_p50_ms,
        memory,
        viewers: args.viewers,
        half_open: args.half_open,
    })
}

/// The console's memory while viewers come and go: every second one viewer more or one
/// less (a fixed pseudo-random walk between none and all), sampled every 10 s after a
/// 30 s warm-up.
fn memory_run(
    pid: u32,
    port: u16,
    args: &BenchConsoleArgs,
    stack: &mut Stack,
) -> Result<MemoryFigures, ConsoleBenchError> {
    let duration = Duration::from_secs_f64(args.memory_run_s);
    let started = Instant::now();
    let mut viewers: Vec<Viewers> = Vec::new();
    let mut opened = 0u64;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut samples = Vec::new();
    let mut next_sample = started + Duration::from_secs(30).min(duration / 4);
    while started.elapsed() < duration {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let open = viewers.is_empty() || (viewers.len() < args.viewers && state.is_multiple_of(2));
        if open {
            // Each from an address of its own within the per-address bounds.
            viewers.push(
                Viewers::open_from(port, 1, Ipv4Addr::new(127, 0, 5, (opened % 200) as u8 + 1))
                    .map_err(failed)?,
            );
            opened += 1;
        } else {
            let index = (state >> 8) as usize % viewers.len();
            viewers.swap_remove(index).close();
        }
        if Instant::now() >= next_sample {
            let figures =
                crate::soak::procs::figures(pid).ok_or_else(|| failed("the console is gone"))?;
            samples.push(figures.private_kib);
            next_sample += Duration::from_secs(10);
            stack.check_running()?;
        }
        std::thread::sleep(Duration::from_secs(1));
    }
    for viewer in viewers {
        viewer.close();
    }
    Ok(MemoryFigures {
        duration_s: duration.as_secs_f64(),
        samples: samples.len(),
        first_kib: samples.first().copied().unwrap_or(0),
        last_kib: samples.last().copied().unwrap_or(0),
        max_kib: samples.iter().copied().max().unwrap_or(0),
        viewers_opened: opened,
    })
}
