//! The console's HTTP server: hyper (HTTP/1.1) on a tokio runtime of its own (two worker
//! threads; the only async code in the console), the routes in [`crate::routes`].
//!
//! Bounds, so that no client (slow, half-open, or many) can hold what the operator needs:
//! - connections: per client address and in all ([`Limits`]); a connection over the bound is
//!   answered 503 at once and closed;
//! - request headers: the whole head within [`HEADER_TIMEOUT`] (hyper's header read timeout,
//!   which also closes a keep-alive connection idle that long) and at most
//!   [`MAX_HEAD_BYTES`];
//! - request bodies: at most [`MAX_BODY_BYTES`] and within [`BODY_TIMEOUT`] (tower-http);
//! - requests: answered within the request timeout (tower-http; set above the command
//!   lanes' own bound, so a command's answer is never cut);
//! - push connections: see [`crate::push`] and [`crate::admission`].

use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use hyper::StatusCode;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tower::ServiceBuilder;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::timeout::{RequestBodyTimeoutLayer, TimeoutLayer};

use crate::admission::Limits;
use crate::routes::route;
use crate::shared::Shared;

/// Longest time a client may take to send a request's head (and longest idle keep-alive).
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(5);
/// Longest time a client may take to send a request's body.
pub const BODY_TIMEOUT: Duration = Duration::from_secs(5);
/// Largest request head, bytes (hyper's read buffer; its minimum is 8 KiB).
pub const MAX_HEAD_BYTES: usize = 16 * 1024;
/// Largest request body, bytes.
pub const MAX_BODY_BYTES: usize = 16 * 1024;
/// How often a busy listening address is tried again.
const BIND_RETRY: Duration = Duration::from_secs(2);

/// How the server runs.
#[derive(Debug, Clone, Copy)]
pub struct ServerSettings {
    pub listen: SocketAddr,
    pub limits: Limits,
    /// Longest time to answer one request.
    pub request_timeout: Duration,
}

/// IPv4 clients seen through an IPv6 socket count as their IPv4 address.
fn client_address(peer: SocketAddr) -> IpAddr {
    match peer.ip() {
        IpAddr::V6(v6) => v6.to_ipv4_mapped().map_or(IpAddr::V6(v6), IpAddr::V4),
        v4 => v4,
    }
}

/// Runs the server on a runtime of its own until `shutdown` turns true; `bound` receives the
/// address once listening.
pub fn run_server(
    shared: Arc<Shared>,
    settings: ServerSettings,
    shutdown: watch::Receiver<bool>,
    bound: Arc<Mutex<Option<SocketAddr>>>,
) -> std::io::Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("console-http")
        .enable_io()
        .enable_time()
        .build()?;
    runtime.block_on(serve(shared, settings, shutdown, bound));
    // Connections still open (push sessions) end with the runtime.
    runtime.shutdown_timeout(Duration::from_secs(1));
    Ok(())
}

/// Binds the address; while it is taken (another console, another program), logs it and
/// tries again every [`BIND_RETRY`] instead of failing: a busy port must not stop the stack
/// (the supervisor stops everything when a process fails for good). `None` at shutdown.
async fn bind_retrying(
    address: SocketAddr,
    shutdown: &mut watch::Receiver<bool>,
) -> Option<TcpListener> {
    let mut warned = false;
    while !*shutdown.borrow() {
        match TcpListener::bind(address).await {
            Ok(listener) => return Some(listener),
            Err(error) => {
                if !warned {
                    tracing::error!(%address, %error, "console cannot listen; retrying every {} s",
                        BIND_RETRY.as_secs());
                    warned = true;
                }
                tokio::select! {
                    _ = tokio::time::sleep(BIND_RETRY) => {}
                    _ = shutdown.changed() => {}
                }
            }
        }
    }
    None
}

async fn serve(
    shared: Arc<Shared>,
    settings: ServerSettings,
    mut shutdown: watch::Receiver<bool>,
    bound: Arc<Mutex<Option<SocketAddr>>>,
) {
    let Some(listener) = bind_retrying(settings.listen, &mut shutdown).await else {
        return;
    };
    if let Ok(address) = listener.local_addr() {
        tracing::info!(%address, "console serving: open http://{address}");
        *bound.lock().unwrap_or_else(|p| p.into_inner()) = Some(address);
    }
    loop {
        let accepted = tokio::select! {
            accepted = listener.accept() => accepted,
            _ = shutdown.changed() => break,
        };
        match accepted {
            Ok((stream, peer)) => admit(&shared, &settings, stream, peer),
            Err(error) => {
                // Out of descriptors and the like: wait a little rather than spin.
                tracing::warn!(%error, "accept failed");
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    }
}

/// Admits one connection (or refuses it at once) and serves it on a task of its own.
fn admit(shared: &Arc<Shared>, settings: &ServerSettings, stream: TcpStream, peer: SocketAddr) {
    let address = client_address(peer);
    let slot = match shared.admission.connect(address) {
        Ok(slot) => Arc::new(slot),
        Err(refusal) => {
            tracing::debug!(%peer, %refusal, "connection refused");
            let body = refusal.to_string();
            let answer = format!(
                "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: {}\r\nRetry-After: 5\r\nConnection: close\r\n\r\n{body}",
                body.len()
            );
            // Best effort, never waiting: the socket is new, its buffer empty.
            let _ = stream.try_write(answer.as_bytes());
            return;
        }
    };
    let _ = stream.set_nodelay(true);
    let shared = shared.clone();
    let request_timeout = settings.request_timeout;
    tokio::spawn(async move {
        let service = ServiceBuilder::new()
            .layer(RequestBodyLimitLayer::new(MAX_BODY_BYTES))
            .layer(TimeoutLayer::with_status_code(
                StatusCode::SERVICE_UNAVAILABLE,
                request_timeout,
            ))
            .layer(RequestBodyTimeoutLayer::new(BODY_TIMEOUT))
            .service_fn(move |request| route(shared.clone(), slot.clone(), request));
        let connection = http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(HEADER_TIMEOUT)
            .max_buf_size(MAX_HEAD_BYTES)
            .serve_connection(TokioIo::new(stream), TowerToHyperService::new(service))
            .with_upgrades();
        if let Err(error) = connection.await {
            tracing::trace!(%peer, %error, "connection ended");
        }
    });
}
