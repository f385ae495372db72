//! The console's routes.
//!
//! - `GET /` (and `/app.js`, `/style.css`): the page, from the binary;
//! - `GET /api/live?session=N`: the page's push connection (a WebSocket, [`crate::push`]);
//! - `GET /api/status`: the newest status JSON; `GET /api/camera.jpg`: the newest view
//!   (both for scripts and checks; the page takes them pushed);
//! - `POST /api/command` (`{"token": "...", "session": N, "command": {"command": "pause",
//!   ...}}`; the e-stop needs no token) and `POST /api/mark` (`{"text": "..."}`): the same as
//!   over the push connection, for a client without one.
//!
//! A command a lane cannot send is answered at once, 503 with `"unreachable": true` and the
//! reason.

use std::convert::Infallible;
use std::sync::Arc;
use std::sync::atomic::Ordering;

use bytes::Bytes;
use http_body_util::{BodyExt, Full, LengthLimitError};
use hyper::body::Body;
use hyper::header::{self, HeaderValue};
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::TokioIo;
use serde_json::Value;
use tokio_tungstenite::WebSocketStream;
use tokio_tungstenite::tungstenite::handshake::derive_accept_key;
use tokio_tungstenite::tungstenite::protocol::{Role, WebSocketConfig};

use crate::admission::ConnectionSlot;
use crate::operator_api::{self, PostedMark};
use crate::page;
use crate::push::{self, Slots};
use crate::shared::Shared;

/// Largest message a page may send on its push connection, bytes.
const MAX_PAGE_MESSAGE_BYTES: usize = 16 * 1024;

type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// A response with a body from memory.
pub type Reply = Response<Full<Bytes>>;

fn reply(status: u16, content_type: &'static str, body: impl Into<Bytes>) -> Reply {
    let mut response = Response::new(Full::new(body.into()));
    *response.status_mut() = StatusCode::from_u16(status).unwrap_or(StatusCode::OK);
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(content_type));
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    response
}

fn json_reply((status, body): (u16, Value)) -> Reply {
    reply(status, "application/json", body.to_string())
}

fn text(status: u16, body: &'static str) -> Reply {
    reply(status, "text/plain; charset=utf-8", body)
}

fn query_param<'a>(query: Option<&'a str>, name: &str) -> Option<&'a str> {
    query?.split('&').find_map(|pair| {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        (key == name).then_some(value)
    })
}

/// Reads the body (bounded by the server's limit and body timeout).
async fn read_body<B>(body: B) -> Result<Bytes, Reply>
where
    B: Body<Data = Bytes>,
    B::Error: Into<BoxError>,
{
    match body.collect().await {
        Ok(collected) => Ok(collected.to_bytes()),
        Err(error) => {
            let error: BoxError = error.into();
            tracing::debug!(%error, "request body refused");
            Err(if error.is::<LengthLimitError>() {
                text(413, "request body too large")
            } else if error.is::<hyper::Error>() {
                text(400, "request body cut short")
            } else {
                text(408, "request body not received in time")
            })
        }
    }
}

/// Answers one request.
pub async fn route<B>(
    shared: Arc<Shared>,
    connection: Arc<ConnectionSlot>,
    request: Request<B>,
) -> Result<Reply, Infallible>
where
    B: Body<Data = Bytes> + Send + 'static,
    B::Error: Into<BoxError>,
{
    let peer = connection.address();
    let path = request.uri().path().to_owned();
    let response = match (request.method(), path.as_str()) {
        (&Method::GET, "/") | (&Method::GET, "/index.html") => {
            reply(200, "text/html; charset=utf-8", page::INDEX_HTML)
        }
        (&Method::GET, "/app.js") => reply(200, "text/javascript; charset=utf-8", page::APP_JS),
        (&Method::GET, "/style.css") => reply(200, "text/css; charset=utf-8", page::STYLE_CSS),
        (&Method::GET, "/favicon.ico") => reply(204, "image/x-icon", Bytes::new()),
        (&Method::GET, "/api/status") => reply(
            200,
            "application/json",
            Bytes::from(shared.status.borrow().clone()),
        ),
        (&Method::GET, "/api/camera.jpg") => match shared.view.latest() {
            Some(view) => {
                let mut response = reply(200, "image/jpeg", view.jpeg());
                for (name, value) in [
                    ("x-view-seq", view.view_seq),
                    ("x-frame-seq", view.frame_seq),
                    ("x-capture-ns", view.capture_ns),
                    ("x-encoded-ns", view.encoded_ns),
                ] {
                    response
                        .headers_mut()
                        .insert(name, HeaderValue::from(value));
                }
                response
            }
            None => text(503, "no camera frame yet"),
        },
        (&Method::GET, "/api/live") => live(shared, connection, request),
        (&Method::POST, "/api/command") => match read_body(request.into_body()).await {
            Ok(body) => match operator_api::parse_command(&body) {
                Ok(posted) => json_reply(operator_api::command(&shared, posted, Some(peer)).await),
                Err(refusal) => json_reply(refusal),
            },
            Err(refusal) => refusal,
        },
        (&Method::POST, "/api/mark") => match read_body(request.into_body()).await {
            Ok(body) => match serde_json::from_slice::<PostedMark>(&body) {
                Ok(posted) => json_reply(operator_api::mark(&shared, posted, Some(peer)).await),
                Err(error) => json_reply((
                    400,
                    serde_json::json!({"accepted": false, "reason": format!("bad request: {error}")}),
                )),
            },
            Err(refusal) => refusal,
        },
        (_, "/api/command" | "/api/mark") => text(405, "POST it"),
        _ => text(404, "not found"),
    };
    tracing::trace!(%peer, %path, status = response.status().as_u16(), "request");
    Ok(response)
}

/// The push connection's upgrade: checks the WebSocket handshake, admits the session (the
/// controlling one beyond the watchers' share), answers 101 and runs the session once hyper
/// hands the connection over.
fn live<B>(shared: Arc<Shared>, connection: Arc<ConnectionSlot>, mut request: Request<B>) -> Reply
where
    B: Send + 'static,
{
    let headers = request.headers();
    let upgrade = headers
        .get(header::UPGRADE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.eq_ignore_ascii_case("websocket"));
    let Some(key) = headers.get(header::SEC_WEBSOCKET_KEY).cloned() else {
        return text(400, "a WebSocket handshake expected");
    };
    if !upgrade
        || headers
            .get(header::SEC_WEBSOCKET_VERSION)
            .is_none_or(|v| v.as_bytes() != b"13")
    {
        return text(400, "a WebSocket handshake (version 13) expected");
    }
    let session: u64 = query_param(request.uri().query(), "session")
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let controlling = session != 0 && shared.controlling_session.load(Ordering::Acquire) == session;
    let peer = connection.address();
    let watcher = match shared.admission.watch(peer, controlling) {
        Ok(slot) => slot,
        Err(refusal) => {
            tracing::debug!(%peer, %refusal, "push connection refused");
            let mut response = reply(503, "text/plain; charset=utf-8", refusal.to_string());
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("5"));
            return response;
        }
    };
    let on_upgrade = hyper::upgrade::on(&mut request);
    let slots = Slots {
        connection,
        watcher,
    };
    tokio::spawn(async move {
        match on_upgrade.await {
            Ok(upgraded) => {
                let config = WebSocketConfig::default()
                    .max_message_size(Some(MAX_PAGE_MESSAGE_BYTES))
                    .max_frame_size(Some(MAX_PAGE_MESSAGE_BYTES));
                let socket = WebSocketStream::from_raw_socket(
                    TokioIo::new(upgraded),
                    Role::Server,
                    Some(config),
                )
                .await;
                push::run_session(socket, shared, peer, slots).await;
            }
            Err(error) => tracing::debug!(%peer, %error, "push connection not upgraded"),
        }
    });
    let mut response = Response::new(Full::new(Bytes::new()));
    *response.status_mut() = StatusCode::SWITCHING_PROTOCOLS;
    let headers = response.headers_mut();
    headers.insert(header::UPGRADE, HeaderValue::from_static("websocket"));
    headers.insert(header::CONNECTION, HeaderValue::from_static("Upgrade"));
    if let Ok(accept) = HeaderValue::from_str(&derive_accept_key(key.as_bytes())) {
        headers.insert(header::SEC_WEBSOCKET_ACCEPT, accept);
    }
    response
}
