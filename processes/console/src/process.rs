//! `harvest console`: threads and routes.
//!
//! - the **status thread** (this process's main loop, a wait set at 10 Hz) reads the channels
//!   into the [`StatusBoard`] and stores its JSON; it also sends the heartbeat;
//! - the **camera-view thread** ([`run_camera_view`]) encodes the view at `--view-rate-hz`;
//! - two **command lanes** ([`Lane`]) send what a page posts on `operator/command` and wait
//!   for each acknowledgement (bounded by `--ack-timeout-ms`): the **e-stop lane** carries the
//!   emergency stop only, so a stop goes out at once even while another command's answer is
//!   pending; the **command lane** carries every other command, one at a time. Whether each
//!   lane can reach the executive is part of the status (`links`), and the page says so;
//! - the **HTTP threads**, one per connection ([`crate::http`]).
//!
//! Routes: `GET /` (and `/app.js`, `/style.css`), `GET /api/status`, `GET
//! /api/camera.jpg[?after=VIEW_SEQ]` (waits up to 1 s for a view newer than `after`),
//! `GET /api/clock` (the stack clock, for the page's latency estimate), `POST /api/command`
//! (`{"token": "...", "session": N, "command": {"command": "pause", ...}}`; the e-stop needs
//! no token). A command a lane cannot send is answered at once, 503 with `"unreachable": true`
//! and the reason.
//!
//! The console commands nothing by itself: killing it changes nothing for the robot (in
//! manual mode, the executive stops a motion whose controlling page is silent for 500 ms).

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use harvest_ipc::catalogue::{
    ARM_STATE, ARM_TARGET, HARVEST_EVENTS, OPERATOR_ACK, OPERATOR_MODE, PERCEPTION_APPLES,
    PROCESS_HEALTH, VACUUM_STATE,
};
use harvest_ipc::payloads::{OperatorModeCode, OperatorRefusalCode, ProcessRunState};
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter,
};
use harvest_operator::Command;
use harvest_operator::request::CommandRequest;
use serde::Deserialize;
use serde_json::json;

use crate::camera_view::{CameraView, ViewSettings, run_camera_view};
use crate::command_lane::{Lane, LaneAnswer};
use crate::error::ConsoleError;
use crate::http::{Handler, Request, Response, serve};
use crate::page;
use crate::status_board::StatusBoard;

/// Status refresh period.
const STATUS_PERIOD: Duration = Duration::from_millis(100);
/// How often a busy listening address is tried again.
const BIND_RETRY: Duration = Duration::from_secs(2);
/// Longest wait of `/api/camera.jpg?after=N` for a newer view.
const VIEW_WAIT: Duration = Duration::from_secs(1);

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
}

/// What the HTTP threads share.
struct Shared {
    view: CameraView,
    status: Mutex<Arc<[u8]>>,
    /// The emergency stop's own lane.
    estop_lane: Lane,
    /// Every other command.
    command_lane: Lane,
    ack_timeout: Duration,
}

/// A command as the page posts it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PostedCommand {
    #[serde(default)]
    token: String,
    session: u64,
    command: CommandRequest,
}

fn refusal_name(code: u8) -> Option<String> {
    OperatorRefusalCode::from_code(code).map(|c| format!("{c:?}"))
}

fn command_response(shared: &Shared, request: &Request) -> Response {
    let posted: PostedCommand = match serde_json::from_slice(&request.body) {
        Ok(posted) => posted,
        Err(error) => {
            let body = json!({"accepted": false, "reason": format!("bad request: {error}")});
            return Response::json(400, body.to_string().into_bytes());
        }
    };
    let command = match posted.command.to_command() {
        Ok(command) => command,
        Err(error) => {
            let body = json!({"accepted": false, "refusal": "UnknownCommand", "reason": error.to_string()});
            return Response::json(400, body.to_string().into_bytes());
        }
    };
    let client = format!(
        "console {}",
        request
            .peer
            .map_or_else(|| "?".to_owned(), |peer| peer.ip().to_string())
    );
    let message = command.to_message(0, posted.session, &posted.token, &client);
    let lane = if command == Command::EmergencyStop {
        &shared.estop_lane
    } else {
        &shared.command_lane
    };
    let answer = lane.submit(message);
    // The lane answers within its acknowledgement timeout once it takes the command; the margin
    // covers a command waiting behind another one on the command lane.
    match answer.recv_timeout(2 * shared.ack_timeout + Duration::from_millis(500)) {
        Ok(LaneAnswer::Ack(ack)) => {
            let body = json!({
                "accepted": ack.accepted != 0,
                "reason": ack.reason.as_str(),
                "refusal": refusal_name(ack.refusal),
                "mode": OperatorModeCode::from_code(ack.mode).map(OperatorModeCode::name),
                "motion_duration_ms": ack.motion_duration_ms,
            });
            Response::json(200, body.to_string().into_bytes())
        }
        Ok(LaneAnswer::Unreachable(problem)) => Response::json(
            503,
            json!({"accepted": false, "unreachable": true, "reason": format!(
                "the console cannot reach the executive: {problem}"
            )})
            .to_string()
            .into_bytes(),
        ),
        Ok(LaneAnswer::NoAnswer) | Err(_) => Response::json(
            504,
            json!({"accepted": false, "reason": format!(
                "sent; no answer from the executive within {} ms (is it running?)",
                shared.ack_timeout.as_millis()
            )})
            .to_string()
            .into_bytes(),
        ),
    }
}

fn camera_response(shared: &Shared, request: &Request) -> Response {
    let frame = match request.query_param("after").and_then(|s| s.parse().ok()) {
        Some(after) => shared.view.wait_newer(after, VIEW_WAIT),
        None => shared.view.latest(),
    };
    match frame {
        Some(frame) => Response::new(200, "image/jpeg", frame.jpeg.clone())
            .with_header("X-View-Seq", frame.view_seq.to_string())
            .with_header("X-Frame-Seq", frame.frame_seq.to_string())
            .with_header("X-Capture-Ns", frame.capture_ns.to_string())
            .with_header("X-Encoded-Ns", frame.encoded_ns.to_string()),
        None => Response::text(503, "no camera frame yet"),
    }
}

fn route(shared: &Shared, request: &Request) -> Response {
    match (request.method.as_str(), request.path.as_str()) {
        ("GET", "/") | ("GET", "/index.html") => {
            Response::new(200, "text/html; charset=utf-8", page::INDEX_HTML.as_bytes())
        }
        ("GET", "/app.js") => Response::new(
            200,
            "text/javascript; charset=utf-8",
            page::APP_JS.as_bytes(),
        ),
        ("GET", "/style.css") => {
            Response::new(200, "text/css; charset=utf-8", page::STYLE_CSS.as_bytes())
        }
        ("GET", "/favicon.ico") => Response::new(204, "image/x-icon", &b""[..]),
        ("GET", "/api/status") => Response::json(
            200,
            shared
                .status
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .clone(),
        ),
        ("GET", "/api/camera.jpg") => camera_response(shared, request),
        ("GET", "/api/clock") => Response::json(
            200,
            format!("{{\"now_ns\":{}}}", MonotonicClock::read_ns()).into_bytes(),
        ),
        ("POST", "/api/command") => command_response(shared, request),
        (_, "/api/command") => Response::text(405, "POST a command"),
        _ => Response::text(404, "not found"),
    }
}

/// Binds `address`; while it is taken (another console, another program), logs it and tries
/// again every [`BIND_RETRY`] instead of failing: a busy port must not stop the stack (the
/// supervisor stops everything when a process fails for good). `None` once `stop` is set.
fn bind_retrying(address: SocketAddr, stop: &AtomicBool) -> Option<TcpListener> {
    let mut warned = false;
    while !stop.load(Ordering::Acquire) {
        match TcpListener::bind(address) {
            Ok(listener) => return Some(listener),
            Err(error) => {
                if !warned {
                    tracing::error!(%address, %error, "console cannot listen; retrying every {} s",
                        BIND_RETRY.as_secs());
                    warned = true;
                }
                // Not a hot path: a retry of a failed bind.
                std::thread::sleep(BIND_RETRY);
            }
        }
    }
    None
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
    let ack_timeout = Duration::from_millis(args.ack_timeout_ms);
    let (estop_lane, estop_thread) = Lane::spawn(
        "e-stop",
        domain,
        format!("{process_name}-estop"),
        ack_timeout,
        stop.clone(),
    )?;
    let (command_lane, command_thread) = Lane::spawn(
        "command",
        domain,
        format!("{process_name}-cmd"),
        ack_timeout,
        stop.clone(),
    )?;
    let shared = Arc::new(Shared {
        view: CameraView::default(),
        status: Mutex::new(Arc::from(&b"{}"[..])),
        estop_lane,
        command_lane,
        ack_timeout,
    });
    let settings = ViewSettings {
        rate_hz: args.view_rate_hz,
        scale: args.view_scale,
        jpeg_quality: args.jpeg_quality,
    };

    let spawn = |name: &str, work: Box<dyn FnOnce() -> Result<(), ConsoleError> + Send>| {
        std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(work)
            .map_err(|error| ConsoleError::Thread(format!("{name} thread: {error}")))
    };
    let view_thread = {
        let (shared, domain, name) = (
            shared.clone(),
            domain.clone(),
            format!("{process_name}-view"),
        );
        spawn(
            "console-view",
            Box::new(move || run_camera_view(&domain, &name, settings, &shared.view)),
        )?
    };
    let bound: Arc<Mutex<Option<SocketAddr>>> = Arc::new(Mutex::new(None));
    let http_thread = {
        let handler_shared = shared.clone();
        let handler: Handler = Arc::new(move |request: &Request| route(&handler_shared, request));
        let (stop, bound, listen) = (stop.clone(), bound.clone(), args.listen);
        std::thread::Builder::new()
            .name("console-accept".to_owned())
            .spawn(move || {
                if let Some(listener) = bind_retrying(listen, &stop) {
                    if let Ok(address) = listener.local_addr() {
                        tracing::info!(%address, "console serving: open http://{address}");
                        *bound.lock().unwrap_or_else(|p| p.into_inner()) = Some(address);
                    }
                    serve(listener, handler, stop);
                }
            })
            .map_err(|error| ConsoleError::Thread(format!("accept thread: {error}")))?
    };

    let result = run_status(domain, process_name, &shared);

    stop.store(true, Ordering::Release);
    // Wake the accept loop so it sees the stop.
    if let Some(address) = *bound.lock().unwrap_or_else(|p| p.into_inner()) {
        let _ = TcpStream::connect_timeout(&address, Duration::from_millis(200));
    }
    let _ = http_thread.join();
    match view_thread.join() {
        Ok(Ok(())) => {}
        Ok(Err(error)) => tracing::warn!(thread = "view", %error, "console thread failed"),
        Err(_) => tracing::warn!(thread = "view", "console thread panicked"),
    }
    for (name, thread) in [("e-stop", estop_thread), ("command", command_thread)] {
        if thread.join().is_err() {
            tracing::warn!(thread = name, "console lane panicked");
        }
    }
    result
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
            status["links"] = json!({
                "estop": shared.estop_lane.status_json(),
                "commands": shared.command_lane.status_json(),
            });
            let text = status.to_string();
            *shared
                .status
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner()) = Arc::from(text.into_bytes());
            updates += 1;
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    Ok(())
}
