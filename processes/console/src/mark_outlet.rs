//! The operator's marks from the page (the mark button): a thread with its own node and
//! `operator/mark` publisher, as `harvest ctl mark "text"` sends them. The recorder files a
//! clip of its flight recorder around each mark. A mark commands nothing, so it needs no
//! control token and does not go through the executive. The publisher stays open for the
//! console's life, so a mark's sample outlives the request that made it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::thread::JoinHandle;
use std::time::Duration;

use harvest_ipc::catalogue::OPERATOR_MARK;
use harvest_ipc::payloads::OperatorMark;
use harvest_ipc::{Context, Domain, FixedString, MonotonicClock, Publisher};
use tokio::sync::oneshot;

use crate::error::ConsoleError;

/// What became of one mark: when it was made (ns, stack clock), or why it was not sent.
pub type MarkAnswer = Result<u64, String>;

struct MarkJob {
    text: String,
    source: String,
    reply: oneshot::Sender<MarkAnswer>,
}

/// The mark thread's inbox (module docs).
pub struct MarkOutlet {
    jobs: Mutex<mpsc::Sender<MarkJob>>,
}

/// The publisher; the context (the node) outlives it.
struct Port {
    publisher: Publisher<OperatorMark>,
    _context: Context,
}

impl MarkOutlet {
    /// Starts the thread (node `node_name` in `domain`); it ends once `stop` is set.
    pub fn spawn(
        domain: &Domain,
        node_name: String,
        stop: Arc<AtomicBool>,
    ) -> Result<(Self, JoinHandle<()>), ConsoleError> {
        let (jobs_in, jobs) = mpsc::channel::<MarkJob>();
        let domain = domain.clone();
        let thread = std::thread::Builder::new()
            .name("console-mark".to_owned())
            .spawn(move || run(&domain, &node_name, &jobs, &stop))
            .map_err(|error| ConsoleError::Thread(format!("mark thread: {error}")))?;
        Ok((
            Self {
                jobs: Mutex::new(jobs_in),
            },
            thread,
        ))
    }

    /// Hands a mark to the thread; the answer comes on the returned receiver.
    pub fn submit(&self, text: String, source: String) -> oneshot::Receiver<MarkAnswer> {
        let (reply, answer) = oneshot::channel();
        let sent = self
            .jobs
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .send(MarkJob {
                text,
                source,
                reply,
            });
        if let Err(mpsc::SendError(job)) = sent {
            let _ = job
                .reply
                .send(Err("the console's mark thread has ended".to_owned()));
        }
        answer
    }
}

fn open(domain: &Domain, node_name: &str) -> Result<Port, String> {
    let context = Context::new(domain, node_name).map_err(|error| error.to_string())?;
    let publisher = context
        .publisher(OPERATOR_MARK)
        .map_err(|error| error.to_string())?;
    Ok(Port {
        publisher,
        _context: context,
    })
}

fn run(domain: &Domain, node_name: &str, jobs: &mpsc::Receiver<MarkJob>, stop: &AtomicBool) {
    // Opened at the first mark (and again after a failure), not before: most runs mark nothing.
    let mut port: Option<Port> = None;
    while !stop.load(Ordering::Acquire) {
        // Bounded so the thread notices the shutdown; a mark wakes it at once.
        let job = match jobs.recv_timeout(Duration::from_millis(500)) {
            Ok(job) => job,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        };
        if port.is_none() {
            port = open(domain, node_name)
                .inspect_err(|error| tracing::error!(%error, "operator/mark not opened"))
                .ok();
        }
        let answer = match port.as_mut() {
            None => Err("cannot open operator/mark (see the console's log)".to_owned()),
            Some(open) => {
                let marked_ns = MonotonicClock::read_ns();
                let sent = open.publisher.publish_with(marked_ns, |mark| {
                    mark.text = FixedString::new(&job.text);
                    mark.source = FixedString::new(&job.source);
                });
                match sent {
                    Ok(_) => {
                        tracing::info!(text = %job.text, source = %job.source, "operator mark");
                        Ok(marked_ns)
                    }
                    Err(error) => {
                        port = None;
                        Err(format!("operator/mark: {error}"))
                    }
                }
            }
        };
        let _ = job.reply.send(answer);
    }
}
