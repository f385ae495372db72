//! `harvest console`: the threads.
//!
//! - the **status thread** (this process's main loop, a wait set at 10 Hz) reads the channels
//!   into the [`StatusBoard`] and hands its JSON to the push connections; it also sends the
//!   heartbeat and notes which session the executive says is in control;
//! - the **camera-view thread** ([`run_camera_view`]) encodes the view at `--view-rate-hz`;
//! - two **command lanes** ([`Lane`]) send what a page sends on `operator/command` and wait
//!   for each acknowledgement (bounded by `--ack-timeout-ms`): the **e-stop lane** carries the
//!   emergency stop only, so a stop goes out at once even while another command's answer is
//!   pending; the **command lane** carries every other command, one at a time. Whether each
//!   lane can reach the executive is part of the status (`links`), and the page says so;
//! - the **mark thread** ([`MarkOutlet`]) publishes the operator's marks;
//! - the **server** ([`crate::server`]): hyper on a tokio runtime with two workers, the routes
//!   in [`crate::routes`], each page's push connection in [`crate::push`].
//!
//! The console commands nothing by itself: killing it changes nothing for the robot (in
//! manual mode, the executive stops a motion whose controlling page is silent for 500 ms).

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use harvest_ipc::catalogue::{
    ARM_STATE, ARM_TARGET, HARVEST_EVENTS, OPERATOR_ACK, OPERATOR_MODE, PERCEPTION_APPLES,
    PROCESS_HEALTH, VACUUM_STATE,
};
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter,
};
use serde_json::json;
use tokio::sync::watch;
use tokio_tungstenite::tungstenite::Utf8Bytes;

use crate::admission::{Admission, Limits};
use crate::camera_view::{CameraView, ViewSettings, run_camera_view};
use crate::command_lane::{Lane, ipc_port_opener};
use crate::error::ConsoleError;
use crate::mark_outlet::MarkOutlet;
use crate::server::{ServerSettings, run_server};
use crate::shared::Shared;
use crate::stack_clock::StackClock;
use crate::status_board::StatusBoard;

/// Status refresh period.
const STATUS_PERIOD: Duration = Duration::from_millis(100);

/// `harvest console` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct ConsoleArgs {
    /// Address to serve on (`0.0.0.0:8080` for the field network).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub listen: SocketAddr,
    /// Camera views per second.
    #[arg(long, default_value_t = 10.0)]
    pub view_rate_hz: f64,
    /// Camera pixels per view pixel (3: 640x360 from 1920x1080).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub view_scale: u32,
    /// JPEG quality of the view, 1-100.
    #[arg(long, default_value_t = 70, value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg_quality: u8,
    /// How long a command waits for the executive's answer, ms.
    #[arg(long, default_value_t = 1500, value_parser = clap::value_parser!(u64).range(100..=60_000))]
    pub ack_timeout_ms: u64,
    /// Pages watching at once (the controlling page is admitted beyond this).
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub max_watchers: u64,
    /// Pages watching at once from one client address.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(1..=1024))]
    pub max_watchers_per_address: u64,
    /// Open connections from one client address.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u64).range(4..=4096))]
    pub max_connections_per_address: u64,
}

impl ConsoleArgs {
    /// The admission limits these options set.
    pub fn limits(&self) -> Limits {
        Limits {
            connections_per_address: self.max_connections_per_address as usize,
            watchers_total: self.max_watchers as usize,
            watchers_per_address: self.max_watchers_per_address as usize,
            ..Limits::default()
        }
    }

    /// How long a command waits for the executive's answer.
    pub fn ack_timeout(&self) -> Duration {
        Duration::from_millis(self.ack_timeout_ms)
    }

    /// What the threads and the server share, around the two lanes and the marks.
    pub fn shared(
        &self,
        estop_lane: Lane,
        command_lane: Lane,
        marks: Option<MarkOutlet>,
    ) -> Arc<Shared> {
        Arc::new(Shared {
            view: CameraView::default(),
            status: watch::Sender::new(Utf8Bytes::from_static("{\"type\":\"status\"}")),
            estop_lane,
            command_lane,
            marks,
            ack_timeout: self.ack_timeout(),
            controlling_session: AtomicU64::new(0),
            admission: Admission::new(self.limits()),
            clock: StackClock::default(),
        })
    }
}

/// The server on its thread (hyper on tokio), until [`ConsoleServer::stop`].
pub struct ConsoleServer {
    shutdown: watch::Sender<bool>,
    thread: std::thread::JoinHandle<std::io::Result<()>>,
}

impl ConsoleServer {
    /// Serves `shared` on `args.listen`.
    pub fn start(shared: Arc<Shared>, args: &ConsoleArgs) -> Result<Self, ConsoleError> {
        let (shutdown, shutdown_seen) = watch::channel(false);
        let server = ServerSettings {
            listen: args.listen,
            limits: args.limits(),
            // Above the command lanes' own bound (twice the acknowledgement timeout and a
            // margin), so a command's answer is never cut short.
            request_timeout: 2 * args.ack_timeout() + Duration::from_secs(2),
        };
        let bound = Arc::new(Mutex::new(None));
        let thread = std::thread::Builder::new()
            .name("console-server".to_owned())
            .spawn(move || run_server(shared, server, shutdown_seen, bound))
            .map_err(|error| ConsoleError::Thread(format!("server thread: {error}")))?;
        Ok(Self { shutdown, thread })
    }

    /// Stops serving and waits for the server's thread.
    pub fn stop(self) {
        let _ = self.shutdown.send(true);
        match self.thread.join() {
            Ok(Ok(())) => {}
            Ok(Err(error)) => tracing::warn!(%error, "console server failed"),
            Err(_) => tracing::warn!("console server panicked"),
        }
    }
}

/// Waits for the console's helper threads (lanes, marks), naming any that panicked.
pub fn join_threads(threads: Vec<(&str, std::thread::JoinHandle<()>)>) {
    for (name, thread) in threads {
        if thread.join().is_err() {
            tracing::warn!(thread = name, "console thread panicked");
        }
    }
}

/// Runs the console until SIGINT/SIGTERM.
pub fn run(args: &ConsoleArgs, domain: &Domain, process_name: &str) -> Result<(), ConsoleError> {
    if !(args.view_rate_hz.is_finite() && (0.5..=30.0).contains(&args.view_rate_hz)) {
        return Err(ConsoleError::Thread(format!(
            "--view-rate-hz {}: expected 0.5 to 30",
            args.view_rate_hz
        )));
    }
    let stop = Arc::new(AtomicBool::new(false));
    let (estop_lane, estop_thread) = Lane::spawn(
        "e-stop",
        ipc_port_opener(domain, format!("{process_name}-estop")),
        args.ack_timeout(),
        stop.clone(),
    )?;
    let (command_lane, command_thread) = Lane::spawn(
        "command",
        ipc_port_opener(domain, format!("{process_name}-cmd")),
        args.ack_timeout(),
        stop.clone(),
    )?;
    let (marks, mark_thread) =
        MarkOutlet::spawn(domain, format!("{process_name}-mark"), stop.clone())?;
    let shared = args.shared(estop_lane, command_lane, Some(marks));
    let settings = ViewSettings {
        rate_hz: args.view_rate_hz,
        scale: args.view_scale,
        jpeg_quality: args.jpeg_quality,
    };

    let view_thread = {
        let (shared, domain, name) = (
            shared.clone(),
            domain.clone(),
            format!("{process_name}-view"),
        );
        std::thread::Builder::new()
            .name("console-view".to_owned())
            .spawn(move || run_camera_view(&domain, &name, settings, &shared.view))
            .map_err(|error| ConsoleError::Thread(format!("view thread: {error}")))?
    };
    let server = ConsoleServer::start(shared.clone(), args)?;

    let result = run_status(domain, process_name, &shared);

    stop.store(true, Ordering::Release);
    server.stop();
    match view_thread.join() {
        Ok(Ok(())) => {}
        Ok(Err(error)) => tracing::warn!(thread = "view", %error, "console thread failed"),
        Err(_) => tracing::warn!(thread = "view", "console thread panicked"),
    }
    join_threads(vec![
        ("e-stop", estop_thread),
        ("command", command_thread),
        ("mark", mark_thread),
    ]);
    result
}

/// The status the pages get: the board, the newest view, the lanes and the admission counts.
pub fn status_json(board: &StatusBoard, shared: &Shared, now_ns: u64) -> serde_json::Value {
    let view = shared.view.latest().map_or(serde_json::Value::Null, |v| {
        json!({
            "view_seq": v.view_seq,
            "frame_seq": v.frame_seq,
            "capture_ns": v.capture_ns,
            "width_px": v.width_px,
            "height_px": v.height_px,
            "scale": v.scale,
            "work_ms_total": shared.view.work_ns.load(Ordering::Relaxed) as f64 * 1e-6,
        })
    });
    let mut status = board.to_json(now_ns, view);
    status["type"] = json!("status");
    status["links"] = json!({
        "estop": shared.estop_lane.status_json(),
        "commands": shared.command_lane.status_json(),
    });
    status["console"] = shared.admission.status_json();
    status
}

/// Hands `status` to every page's push connection.
pub fn publish_status(shared: &Shared, status: &serde_json::Value) {
    shared
        .status
        .send_replace(Utf8Bytes::from(status.to_string()));
}

/// The status loop (module docs).
fn run_status(domain: &Domain, process_name: &str, shared: &Shared) -> Result<(), ConsoleError> {
    let context = Context::new(domain, process_name)?;
    let mode_in = context.subscriber(OPERATOR_MODE)?;
    let acks_in = context.subscriber_with_buffer(OPERATOR_ACK, 256)?;
    let arms_in = [
        context.subscriber(ARM_STATE[0])?,
        context.subscriber(ARM_STATE[1])?,
    ];
    let targets_in = [
        context.subscriber(ARM_TARGET[0])?,
        context.subscriber(ARM_TARGET[1])?,
    ];
    let vacuum_in = context.subscriber(VACUUM_STATE)?;
    let apples_in = context.subscriber(PERCEPTION_APPLES)?;
    let events_in = context.subscriber_with_buffer(HARVEST_EVENTS, 256)?;
    let health_in = context.subscriber_with_buffer(PROCESS_HEALTH, 256)?;
    let mut health = HealthReporter::new(&context)?;
    let waiter = Waiter::new()?;
    let tick = waiter.attach_interval(STATUS_PERIOD)?;
    let heartbeat = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let mut board = StatusBoard::new(MonotonicClock::read_ns());
    let mut updates = 0u64;
    waiter
        .run(|attachment| -> Result<Flow, ConsoleError> {
            if attachment.has_event_from(&heartbeat) {
                let views = shared.view.latest().map_or(0, |v| v.view_seq);
                health.report(ProcessRunState::Running, updates, "views", views)?;
            }
            if !attachment.has_event_from(&tick) {
                return Ok(Flow::Continue);
            }
            let now_ns = MonotonicClock::read_ns();
            if let Some(mode) = mode_in.receive_latest()? {
                shared
                    .controlling_session
                    .store(mode.controlling_session, Ordering::Release);
                board.on_mode(&mode);
            }
            while let Some(ack) = acks_in.receive()? {
                board.on_ack(&ack, now_ns);
            }
            for i in 0..2 {
                if let Some(state) = arms_in[i].receive_latest()? {
                    board.on_arm_state(i, &state);
                }
                if let Some(target) = targets_in[i].receive_latest()? {
                    board.on_arm_target(i, &target);
                }
            }
            if let Some(state) = vacuum_in.receive_latest()? {
                board.on_vacuum(&state);
            }
            if let Some(set) = apples_in.receive_latest()? {
                board.on_detections(&set);
            }
            while let Some(event) = events_in.receive()? {
                board.on_harvest_event(&event);
            }
            while let Some(beat) = health_in.receive()? {
                board.on_health(&beat, now_ns);
            }
            publish_status(shared, &status_json(&board, shared, now_ns));
            updates += 1;
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    Ok(())
}
