//! A lane to the executive: a thread with its own node, `operator/command` publisher and
//! `operator/ack` subscriber that sends the commands handed to it, one at a time, and waits
//! (bounded) for each answer.
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
use harvest_ipc::payloads::{OperatorAck, OperatorCommand};
use harvest_ipc::{Context, Domain};
use serde_json::{Value, json};
use tokio::sync::oneshot;

use crate::error::ConsoleError;

/// How often a lane without ports tries to open them again.
pub const REOPEN_PERIOD: Duration = Duration::from_secs(1);

/// What became of one command.
#[derive(Debug, Clone, PartialEq)]
pub enum LaneAnswer {
    /// The executive's acknowledgement.
    Ack(OperatorAck),
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
    message: OperatorCommand,
    reply: oneshot::Sender<LaneAnswer>,
}

/// One lane (module docs).
pub struct Lane {
    name: &'static str,
    jobs: Mutex<mpsc::Sender<Job>>,
    state: Arc<LaneState>,
}

impl Lane {
    /// Starts the lane's thread (node `node_name` in `domain`); it ends once `stop` is set.
    pub fn spawn(
        name: &'static str,
        domain: &Domain,
        node_name: String,
        ack_timeout: Duration,
        stop: Arc<AtomicBool>,
    ) -> Result<(Self, JoinHandle<()>), ConsoleError> {
        let (jobs_in, jobs) = mpsc::channel();
        let state = Arc::new(LaneState {
            problem: Mutex::new(Some("starting".to_owned())),
        });
        let thread = {
            let (domain, state) = (domain.clone(), state.clone());
            std::thread::Builder::new()
                .name(format!("console-{name}"))
                .spawn(move || {
                    run_lane(name, &domain, &node_name, &jobs, &state, ack_timeout, &stop);
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

    /// Hands `message` to the lane; the answer comes on the returned receiver (awaited by the
    /// server's tasks; the lane's thread does the blocking wait).
    pub fn submit(&self, message: OperatorCommand) -> oneshot::Receiver<LaneAnswer> {
        let (reply, answer) = oneshot::channel();
        let sent = self
            .jobs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .send(Job { message, reply });
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

/// The lane's ports; the context (the node) outlives the client's ports.
struct Ports {
    client: OperatorClient,
    _context: Context,
}

fn open(domain: &Domain, node_name: &str) -> Result<Ports, String> {
    let context = Context::new(domain, node_name).map_err(|error| error.to_string())?;
    let client = OperatorClient::new(&context).map_err(|error| error.to_string())?;
    Ok(Ports {
        client,
        _context: context,
    })
}

fn run_lane(
    name: &str,
    domain: &Domain,
    node_name: &str,
    jobs: &mpsc::Receiver<Job>,
    state: &LaneState,
    ack_timeout: Duration,
    stop: &AtomicBool,
) {
    let mut ports: Option<Ports> = None;
    let reopen = |ports: &mut Option<Ports>| {
        if ports.is_some() {
            return;
        }
        match open(domain, node_name) {
            Ok(opened) => {
                if state.problem().is_some() {
                    tracing::info!(lane = name, "command lane open");
                }
                state.set(None);
                *ports = Some(opened);
            }
            Err(error) => {
                let problem = format!("cannot open the operator channels: {error}");
                if state.problem().as_deref() != Some(problem.as_str()) {
                    tracing::error!(lane = name, %problem, "command lane down; retrying");
                }
                state.set(Some(problem));
            }
        }
    };
    while !stop.load(Ordering::Acquire) {
        reopen(&mut ports);
        // Bounded so the lane notices the shutdown and reopens its ports; a command wakes it at
        // once.
        let wait = if ports.is_some() {
            Duration::from_millis(500)
        } else {
            REOPEN_PERIOD
        };
        let job = match jobs.recv_timeout(wait) {
            Ok(job) => job,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        };
        reopen(&mut ports);
        let answer = match ports.as_mut() {
            None => LaneAnswer::Unreachable(state.problem().unwrap_or_default()),
            Some(open) => {
                let session = job.message.session_id;
                let sent = open.client.send(job.message).and_then(|request| {
                    open.client
                        .wait_ack(session, request, ack_timeout)
                        .map(|ack| ack.map_or(LaneAnswer::NoAnswer, LaneAnswer::Ack))
                });
                match sent {
                    Ok(answer) => answer,
                    Err(error) => {
                        let problem = format!("operator channels failed: {error}");
                        tracing::error!(lane = name, %problem, "command lane down; reopening");
                        state.set(Some(problem.clone()));
                        ports = None;
                        LaneAnswer::Unreachable(problem)
                    }
                }
            }
        };
        let _ = job.reply.send(answer);
    }
}
