//! A lane to the executive: a thread that sends the commands handed to it, one at a time,
//! through its [`CommandPort`], and waits (bounded) for each answer. On the robot the port is
//! the lane's own node with an `operator/command` publisher and an `operator/ack` subscriber
//! ([`ipc_port_opener`]); a station's console gives it a port over the remote link.
//!
//! The console runs two lanes: one that carries the emergency stop and nothing else, so a stop
//! goes out at once even while another command's answer is pending, and one for every other
//! command. A lane that cannot open its ports (or loses them) says why in its [`LaneState`],
//! which the status board shows, and opens them again (at the next command, else every
//! [`REOPEN_PERIOD`]); a command handed to it meanwhile is answered at once with the reason,
//! never left to time out behind a page that looks alive.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::thread::JoinHandle;
use std::time::Duration;

use harvest_ipc::operator_client::OperatorClient;
use harvest_ipc::payloads::{OperatorAck, OperatorModeCode, OperatorRefusalCode};
use harvest_ipc::{Context, Domain};
use harvest_operator::Command;
use serde_json::{Value, json};
use tokio::sync::oneshot;

use crate::error::ConsoleError;

/// How often a lane without ports tries to open them again.
pub const REOPEN_PERIOD: Duration = Duration::from_secs(1);

/// The executive's answer to one command.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandAnswer {
    pub accepted: bool,
    pub reason: String,
    /// The refusal's code name (`NoToken`, ...), none when accepted.
    pub refusal: Option<String>,
    /// The mode after the command.
    pub mode: Option<String>,
    pub motion_duration_ms: u32,
}

impl CommandAnswer {
    /// The answer an acknowledgement on `operator/ack` carries.
    pub fn from_ack(ack: &OperatorAck) -> Self {
        Self {
            accepted: ack.accepted != 0,
            reason: ack.reason.as_str().to_owned(),
            refusal: if ack.accepted != 0 {
                None
            } else {
                OperatorRefusalCode::from_code(ack.refusal).map(|c| format!("{c:?}"))
            },
            mode: OperatorModeCode::from_code(ack.mode).map(|m| m.name().to_owned()),
            motion_duration_ms: ack.motion_duration_ms,
        }
    }
}

/// One command as a page gives it.
#[derive(Debug, Clone, PartialEq)]
pub struct LaneCommand {
    pub command: Command,
    /// The page's session.
    pub session: u64,
    /// The control token the operator typed (empty for the e-stop).
    pub token: String,
    /// Who sends it, in a few words (`console 10.0.0.7`).
    pub client: String,
}

/// What a lane sends through: one command, then its answer within `ack_timeout` (`None`: no
/// answer). An error means the port is broken; the lane opens a new one.
pub trait CommandPort {
    fn send(
        &mut self,
        command: &LaneCommand,
        ack_timeout: Duration,
    ) -> Result<Option<CommandAnswer>, String>;
}

/// Opens a lane's port (on the lane's thread, again after a failure); the error says why it
/// cannot.
pub type PortOpener = Box<dyn FnMut() -> Result<Box<dyn CommandPort>, String> + Send>;

/// What became of one command.
#[derive(Debug, Clone, PartialEq)]
pub enum LaneAnswer {
    /// The executive's answer.
    Ack(CommandAnswer),
    /// Sent, but no acknowledgement within the lane's timeout.
    NoAnswer,
    /// Not sent (or sent and the ports failed): the lane cannot reach the executive.
    Unreachable(String),
}

/// Whether a lane can reach the executive, shared with the status board.
#[derive(Debug, Default)]
pub struct LaneState {
    /// Why the lane cannot send (`None`: its ports are open).
    problem: Mutex<Option<String>>,
}

impl LaneState {
    fn set(&self, problem: Option<String>) {
        *self.problem.lock().unwrap_or_else(|p| p.into_inner()) = problem;
    }

    /// Why the lane cannot send; `None` while its ports are open.
    pub fn problem(&self) -> Option<String> {
        self.problem
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }
}

struct Job {
    command: LaneCommand,
    reply: oneshot::Sender<LaneAnswer>,
}

/// One lane (module docs).
pub struct Lane {
    name: &'static str,
    jobs: Mutex<mpsc::Sender<Job>>,
    state: Arc<LaneState>,
}

impl Lane {
    /// Starts the lane's thread, sending through the ports `open` makes; it ends once `stop`
    /// is set.
    pub fn spawn(
        name: &'static str,
        open: PortOpener,
        ack_timeout: Duration,
        stop: Arc<AtomicBool>,
    ) -> Result<(Self, JoinHandle<()>), ConsoleError> {
        let (jobs_in, jobs) = mpsc::channel();
        let state = Arc::new(LaneState {
            problem: Mutex::new(Some("starting".to_owned())),
        });
        let thread = {
            let state = state.clone();
            std::thread::Builder::new()
                .name(format!("console-{name}"))
                .spawn(move || {
                    run_lane(name, open, &jobs, &state, ack_timeout, &stop);
                    state.set(Some("console stopping".to_owned()));
                })
                .map_err(|error| ConsoleError::Thread(format!("{name} lane thread: {error}")))?
        };
        Ok((
            Self {
                name,
                jobs: Mutex::new(jobs_in),
                state,
            },
            thread,
        ))
    }

    /// Hands `command` to the lane; the answer comes on the returned receiver (awaited by the
    /// server's tasks; the lane's thread does the blocking wait).
    pub fn submit(&self, command: LaneCommand) -> oneshot::Receiver<LaneAnswer> {
        let (reply, answer) = oneshot::channel();
        let sent = self
            .jobs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .send(Job { command, reply });
        if let Err(mpsc::SendError(job)) = sent {
            let _ = job.reply.send(LaneAnswer::Unreachable(format!(
                "the console's {} lane has ended",
                self.name
            )));
        }
        answer
    }

    /// `{"ok": bool, "problem": text or null}` for the status board.
    pub fn status_json(&self) -> Value {
        let problem = self.state.problem();
        json!({"ok": problem.is_none(), "problem": problem})
    }
}

/// The lane's ports on the robot; the context (the node) outlives the client's ports.
struct IpcPort {
    client: OperatorClient,
    _context: Context,
}

impl CommandPort for IpcPort {
    fn send(
        &mut self,
        command: &LaneCommand,
        ack_timeout: Duration,
    ) -> Result<Option<CommandAnswer>, String> {
        let message =
            command
                .command
                .to_message(0, command.session, &command.token, &command.client);
        let request = self
            .client
            .send(message)
            .map_err(|error| format!("operator channels failed: {error}"))?;
        let ack = self
            .client
            .wait_ack(command.session, request, ack_timeout)
            .map_err(|error| format!("operator channels failed: {error}"))?;
        Ok(ack.as_ref().map(CommandAnswer::from_ack))
    }
}

/// Ports of a node `node_name` in `domain`: `operator/command` out, `operator/ack` in.
pub fn ipc_port_opener(domain: &Domain, node_name: String) -> PortOpener {
    let domain = domain.clone();
    Box::new(move || {
        let context = Context::new(&domain, &node_name)
            .map_err(|error| format!("cannot open the operator channels: {error}"))?;
        let client = OperatorClient::new(&context)
            .map_err(|error| format!("cannot open the operator channels: {error}"))?;
        Ok(Box::new(IpcPort {
            client,
            _context: context,
        }) as Box<dyn CommandPort>)
    })
}

fn run_lane(
    name: &str,
    mut open: PortOpener,
    jobs: &mpsc::Receiver<Job>,
    state: &LaneState,
    ack_timeout: Duration,
    stop: &AtomicBool,
) {
    let mut port: Option<Box<dyn CommandPort>> = None;
    let mut reopen = |port: &mut Option<Box<dyn CommandPort>>| {
        if port.is_some() {
            return;
        }
        match open() {
            Ok(opened) => {
                if state.problem().is_some() {
                    tracing::info!(lane = name, "command lane open");
                }
                state.set(None);
                *port = Some(opened);
            }
            Err(problem) => {
                if state.problem().as_deref() != Some(problem.as_str()) {
                    tracing::error!(lane = name, %problem, "command lane down; retrying");
                }
                state.set(Some(problem));
            }
        }
    };
    while !stop.load(Ordering::Acquire) {
        reopen(&mut port);
        // Bounded so the lane notices the shutdown and reopens its port; a command wakes it at
        // once.
        let wait = if port.is_some() {
            Duration::from_millis(500)
        } else {
            REOPEN_PERIOD
        };
        let job = match jobs.recv_timeout(wait) {
            Ok(job) => job,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        };
        reopen(&mut port);
        let answer = match port.as_mut() {
            None => LaneAnswer::Unreachable(state.problem().unwrap_or_default()),
            Some(open) => match open.send(&job.command, ack_timeout) {
                Ok(answer) => answer.map_or(LaneAnswer::NoAnswer, LaneAnswer::Ack),
                Err(problem) => {
                    tracing::error!(lane = name, %problem, "command lane down; reopening");
                    state.set(Some(problem.clone()));
                    port = None;
                    LaneAnswer::Unreachable(problem)
                }
            },
        };
        let _ = job.reply.send(answer);
    }
}
