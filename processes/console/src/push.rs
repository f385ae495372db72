//! One page's push connection: a WebSocket at `/api/live?session=N`.
//!
//! To the page: the status (text, `{"type": "status", ...}`) at the status rate and each camera
//! view (binary, [`crate::camera_view::push_message`]) at the view rate, always the newest:
//! while the page is still taking one, newer ones replace each other and only the last is sent
//! (a slow page skips views, nothing queues). Answers (`{"type": "answer", "id": K, "status":
//! HTTP status, ...}`) and clock readings (`{"type": "clock", "id": K, "now_ns": ...}`) go
//! before either.
//!
//! From the page: `{"op": "command", "id": K, "token": ..., "session": N, "command": {...}}`,
//! `{"op": "mark", "id": K, "text": ...}` and `{"op": "clock", "id": K}`. A command is handed to
//! its lane as soon as it is read, each on a task of its own, so the e-stop never waits behind
//! another command's answer nor behind views the page has not taken yet.
//!
//! A page that takes nothing for [`SEND_STALL`] or says nothing (not even a pong) for
//! [`READ_IDLE`] is gone: the connection is closed.

use std::net::IpAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use harvest_operator::request::CommandRequest;
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::sync::mpsc;
use tokio_tungstenite::WebSocketStream;
use tokio_tungstenite::tungstenite::{Message, Utf8Bytes};

use crate::admission::{ConnectionSlot, WatcherSlot};
use crate::operator_api::{self, PostedCommand, PostedMark};
use crate::shared::Shared;

/// Longest time the page may take to accept one message.
pub const SEND_STALL: Duration = Duration::from_secs(10);
/// Longest silence from the page (it sends a clock request every 5 s; browsers answer pings).
pub const READ_IDLE: Duration = Duration::from_secs(30);
/// How often the console pings the page.
const PING_PERIOD: Duration = Duration::from_secs(10);
/// Answers waiting for the page (beyond this, a page sending commands faster than it reads
/// its answers loses answers, never commands).
const ANSWERS_QUEUED: usize = 64;

/// A message from the page.
#[derive(Debug, Deserialize)]
#[serde(tag = "op", rename_all = "lowercase", deny_unknown_fields)]
enum PageMessage {
    Command {
        id: u64,
        #[serde(default)]
        token: String,
        session: u64,
        command: CommandRequest,
    },
    Mark {
        id: u64,
        #[serde(default)]
        text: String,
    },
    Clock {
        id: u64,
    },
}

fn answer_text(id: u64, (status, mut body): (u16, Value)) -> Utf8Bytes {
    body["type"] = json!("answer");
    body["id"] = json!(id);
    body["status"] = json!(status);
    Utf8Bytes::from(body.to_string())
}

/// What holds a push connection's places; dropped when the connection ends.
pub struct Slots {
    pub connection: Arc<ConnectionSlot>,
    pub watcher: WatcherSlot,
}

/// Runs one push connection until the page leaves, stalls or the console stops.
pub async fn run_session<S>(
    socket: WebSocketStream<S>,
    shared: Arc<Shared>,
    peer: IpAddr,
    slots: Slots,
) where
    S: AsyncRead + AsyncWrite + Unpin + Send + 'static,
{
    let (mut sink, mut stream) = socket.split();
    let (answers_in, mut answers) = mpsc::channel::<Utf8Bytes>(ANSWERS_QUEUED);
    let reader = {
        let shared = shared.clone();
        tokio::spawn(async move {
            loop {
                let message = match tokio::time::timeout(READ_IDLE, stream.next()).await {
                    Err(_) => {
                        tracing::debug!(%peer, "push connection silent; closing");
                        return;
                    }
                    Ok(None) | Ok(Some(Err(_))) => return,
                    Ok(Some(Ok(message))) => message,
                };
                let text = match message {
                    Message::Text(text) => text,
                    Message::Close(_) => return,
                    // Pongs and pings count as signs of life (tungstenite answers pings).
                    _ => continue,
                };
                handle(&shared, peer, text.as_str(), &answers_in);
            }
        })
    };

    let mut status = shared.status.subscribe();
    let mut views = shared.view.subscribe();
    let mut last_view_seq = views.borrow().as_ref().map_or(0, |view| view.view_seq);
    // The newest status goes out at once; views from the next one on.
    status.mark_changed();
    let mut ping = tokio::time::interval(PING_PERIOD);
    ping.tick().await;
    loop {
        let message = tokio::select! {
            biased;
            answer = answers.recv() => match answer {
                Some(text) => Message::Text(text),
                None => break,
            },
            changed = status.changed() => {
                if changed.is_err() {
                    break;
                }
                Message::Text(status.borrow_and_update().clone())
            }
            changed = views.changed() => {
                if changed.is_err() {
                    break;
                }
                let Some(view) = views.borrow_and_update().clone() else {
                    continue;
                };
                if last_view_seq > 0 && view.view_seq > last_view_seq + 1 {
                    shared
                        .admission
                        .views_skipped
                        .fetch_add(view.view_seq - last_view_seq - 1, Ordering::Relaxed);
                }
                last_view_seq = view.view_seq;
                Message::Binary(view.message.clone())
            }
            _ = ping.tick() => Message::Ping(bytes::Bytes::new()),
        };
        match tokio::time::timeout(SEND_STALL, sink.send(message)).await {
            Ok(Ok(())) => {}
            Ok(Err(error)) => {
                tracing::trace!(%peer, %error, "push connection ended");
                break;
            }
            Err(_) => {
                tracing::debug!(%peer, "page took nothing for {SEND_STALL:?}; closing");
                break;
            }
        }
        if reader.is_finished() {
            break;
        }
    }
    reader.abort();
    let _ = tokio::time::timeout(Duration::from_secs(1), sink.close()).await;
    drop(slots);
}

/// Acts on one message from the page; answers go to `answers`.
fn handle(shared: &Arc<Shared>, peer: IpAddr, text: &str, answers: &mpsc::Sender<Utf8Bytes>) {
    let message: PageMessage = match serde_json::from_str(text) {
        Ok(message) => message,
        Err(error) => {
            let body = json!({"accepted": false, "reason": format!("bad message: {error}")});
            let _ = answers.try_send(answer_text(0, (400, body)));
            return;
        }
    };
    match message {
        PageMessage::Clock { id } => {
            let reading = json!({"type": "clock", "id": id, "now_ns": shared.clock.now_ns()});
            let _ = answers.try_send(Utf8Bytes::from(reading.to_string()));
        }
        PageMessage::Command {
            id,
            token,
            session,
            command,
        } => {
            let (shared, answers) = (shared.clone(), answers.clone());
            let posted = PostedCommand {
                token,
                session,
                command,
            };
            // Handed to its lane now; the answer comes when the executive gives it.
            tokio::spawn(async move {
                let answer = operator_api::command(&shared, posted, Some(peer)).await;
                let _ = answers.send(answer_text(id, answer)).await;
            });
        }
        PageMessage::Mark { id, text } => {
            let (shared, answers) = (shared.clone(), answers.clone());
            tokio::spawn(async move {
                let answer = operator_api::mark(&shared, PostedMark { text }, Some(peer)).await;
                let _ = answers.send(answer_text(id, answer)).await;
            });
        }
    }
}
