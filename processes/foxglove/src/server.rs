//! The Foxglove WebSocket server and the channels the mapping writes to.
//!
//! The SDK queues each client's messages in a bounded queue (`message_backlog_size`) and drops
//! the oldest when it is full, so logging never blocks the bridge and a slow client loses
//! messages instead of building a backlog (its control queue overflowing disconnects it). The
//! server runs in a tokio runtime of its own with one worker thread: the only async code in the
//! stack, kept inside this process.
//!
//! If the address cannot be bound (another stack's bridge on the port), the bridge keeps
//! running and retries every [`BIND_RETRY`]: a viewer must never take the robot down.

use foxglove::{PartialMetadata, RawChannel, WebSocketServer, WebSocketServerHandle};
use harvest_foxglove_mapping::topics::{self, MappedSink, Topic, encode_into};
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often a server that could not bind tries again.
pub const BIND_RETRY: Duration = Duration::from_secs(5);

/// The server could not be set up at all.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// The tokio runtime could not be built.
    #[error("cannot start the WebSocket server's runtime: {0}")]
    Runtime(std::io::Error),
    /// A mapped topic could not be made into a channel (a bug in the topic table).
    #[error("cannot create the Foxglove channel {topic}: {reason}")]
    Channel { topic: &'static str, reason: String },
}

/// The server's channels, one per mapped topic: a [`MappedSink`] that encodes a message only
/// when some client subscribed to its topic.
#[derive(Clone)]
pub struct LiveChannels {
    channels: BTreeMap<&'static str, Arc<RawChannel>>,
    buffer: Vec<u8>,
    /// Messages handed to the server.
    pub sent: u64,
}

impl std::fmt::Debug for LiveChannels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveChannels")
            .field("topics", &self.channels.keys().collect::<Vec<_>>())
            .field("sent", &self.sent)
            .finish()
    }
}

impl LiveChannels {
    /// Creates every mapped topic's channel in `context`.
    pub fn new(context: &Arc<foxglove::Context>) -> Result<Self, ServerError> {
        let mut channels = BTreeMap::new();
        for topic in topics::all() {
            let channel = context
                .channel_builder(topic.name)
                .schema(topic.schema.clone())
                .message_encoding(topic.message_encoding.clone())
                .add_metadata("description", topic.description)
                .build_raw()
                .map_err(|error| ServerError::Channel {
                    topic: topic.name,
                    reason: error.to_string(),
                })?;
            channels.insert(topic.name, channel);
        }
        Ok(Self {
            channels,
            buffer: Vec::new(),
            sent: 0,
        })
    }

    /// True when at least one client is subscribed to `topic`.
    pub fn watched<M>(&self, topic: Topic<M>) -> bool {
        self.channels
            .get(topic.name)
            .is_some_and(|channel| channel.has_sinks())
    }
}

impl MappedSink for LiveChannels {
    type Error = std::convert::Infallible;

    fn write<M: foxglove::Encode>(
        &mut self,
        topic: Topic<M>,
        log_time_ns: u64,
        message: &M,
    ) -> Result<(), Self::Error> {
        let Some(channel) = self.channels.get(topic.name) else {
            return Ok(());
        };
        if !channel.has_sinks() {
            return Ok(());
        }
        if let Err(error) = encode_into(message, &mut self.buffer) {
            tracing::warn!(topic = topic.name, %error, "cannot encode a mapped message");
            return Ok(());
        }
        channel.log_with_meta(&self.buffer, PartialMetadata::with_log_time(log_time_ns));
        self.sent += 1;
        tracing::trace!(topic = topic.name, bytes = self.buffer.len(), "sent");
        Ok(())
    }
}

/// The WebSocket server, started (again) until it is bound.
pub struct Server {
    runtime: tokio::runtime::Runtime,
    context: Arc<foxglove::Context>,
    listen: SocketAddr,
    backlog: usize,
    handle: Option<WebSocketServerHandle>,
    next_attempt: Instant,
    failures: u32,
}

impl Server {
    /// A server for `context`'s channels on `listen`; not started yet ([`Self::ensure_started`]).
    pub fn new(
        context: Arc<foxglove::Context>,
        listen: SocketAddr,
        backlog: usize,
    ) -> Result<Self, ServerError> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("foxglove-ws")
            .enable_all()
            .build()
            .map_err(ServerError::Runtime)?;
        Ok(Self {
            runtime,
            context,
            listen,
            backlog,
            handle: None,
            next_attempt: Instant::now(),
            failures: 0,
        })
    }

    /// Starts the server if it is not running and a retry is due. Logs the first failure at
    /// ERROR and repeats at DEBUG.
    pub fn ensure_started(&mut self) {
        if self.handle.is_some() || Instant::now() < self.next_attempt {
            return;
        }
        let result = WebSocketServer::new()
            .name("harvest")
            .bind(self.listen.ip().to_string(), self.listen.port())
            .message_backlog_size(self.backlog)
            .context(&self.context)
            .tokio_runtime(self.runtime.handle())
            .start_blocking();
        match result {
            Ok(handle) => {
                tracing::info!(
                    "Foxglove WebSocket server on ws://{}:{} (open it in Foxglove or Lichtblick)",
                    self.listen.ip(),
                    handle.port()
                );
                self.handle = Some(handle);
                self.failures = 0;
            }
            Err(error) => {
                self.failures += 1;
                self.next_attempt = Instant::now() + BIND_RETRY;
                if self.failures == 1 {
                    tracing::error!(
                        listen = %self.listen,
                        %error,
                        "cannot start the Foxglove WebSocket server (another bridge on this port? pass --listen); \
                    the bridge keeps running and retries every {BIND_RETRY:?}"
                    );
                } else {
                    tracing::debug!(listen = %self.listen, %error, attempt = self.failures, "server still not started");
                }
            }
        }
    }

    /// True once the server listens.
    pub fn is_running(&self) -> bool {
        self.handle.is_some()
    }

    /// Connected clients.
    pub fn client_count(&self) -> usize {
        self.handle
            .as_ref()
            .map_or(0, WebSocketServerHandle::client_count)
    }

    /// Closes every connection and waits for the server's tasks to end.
    pub fn stop(mut self) {
        if let Some(handle) = self.handle.take() {
            handle.stop().wait_blocking();
        }
        self.runtime.shutdown_timeout(Duration::from_secs(1));
    }
}
