//! Zenoh over loopback TCP, shared memory off: the copying baseline's messages through Zenoh
//! instead of a raw socket. The sender writes the message in place into its own copy, encodes
//! it with the stack's codec (`Payload::encode`) into a pooled buffer that Zenoh takes without
//! copying (`bytes::Bytes::from_owner`; the buffer returns to the pool when Zenoh drops it), and
//! the receiver decodes each sample (`Payload::decode_into`) into its own copy. As in
//! `uds-copy`, `publish_ns` is stamped before encoding, so encode and decode are in the latency.

use super::zenoh_link::{
    LinkEnd, declare_publisher, declare_subscriber, key_expr, open_session, receive_loop,
    wait_for_subscriber, zenoh_error,
};
use super::{OnMessage, ReceivePort, SendPort};
use crate::bench_payload::zeroed_box;
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::{Transport, WakeMode};
use crate::sender_write::PayloadWriter;
use crate::watchdog::Watchdog;
use harvest_ipc::MonotonicClock;
use std::sync::{Arc, Mutex};
use zenoh::bytes::ZBytes;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

const TRANSPORT: Transport = Transport::ZenohTcp;

/// Encoded-message buffers Zenoh has released, ready for the next message.
type BufferPool = Arc<Mutex<Vec<Vec<u8>>>>;

/// One encoded message lent to Zenoh; its buffer goes back to the pool when Zenoh drops it.
struct PooledBuffer {
    bytes: Vec<u8>,
    pool: BufferPool,
}

impl AsRef<[u8]> for PooledBuffer {
    fn as_ref(&self) -> &[u8] {
        &self.bytes
    }
}

impl Drop for PooledBuffer {
    fn drop(&mut self) {
        // A poisoned pool only costs an allocation for a later message.
        if let Ok(mut pool) = self.pool.lock() {
            pool.push(std::mem::take(&mut self.bytes));
        }
    }
}

/// Writes into its own copy, encodes into a pooled buffer, publishes it.
pub struct ZenohTcpSender<T: BenchMessage> {
    publisher: Publisher<'static>,
    message: Box<T>,
    pool: BufferPool,
    key: String,
    payload: &'static str,
    next_seq: u64,
    _session: Session,
}

impl<T: BenchMessage> ZenohTcpSender<T> {
    /// Connects to the receiver at `endpoint` and waits until its subscriber is matched.
    pub fn connect(endpoint: &str, payload: &'static str) -> Result<Self, BenchError> {
        let key = key_expr(payload);
        let session = open_session(TRANSPORT, LinkEnd::Connect(endpoint))?;
        let publisher = declare_publisher(&session, TRANSPORT, &key)?;
        wait_for_subscriber(&publisher, TRANSPORT, &key)?;
        Ok(Self {
            publisher,
            message: zeroed_box(),
            pool: BufferPool::default(),
            key,
            payload,
            next_seq: 1,
            _session: session,
        })
    }

    fn take_buffer(&self) -> Vec<u8> {
        let reused = self.pool.lock().ok().and_then(|mut pool| pool.pop());
        let mut buffer = reused.unwrap_or_else(|| Vec::with_capacity(2 * std::mem::size_of::<T>()));
        buffer.clear();
        buffer
    }
}

impl<T: BenchMessage> SendPort<T> for ZenohTcpSender<T> {
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError> {
        let msg_seq = self.next_seq;
        let publish_ns = writer.write_stamped(&mut *self.message, msg_seq, phase);
        let mut buffer = self.take_buffer();
        self.message
            .encode(&mut buffer)
            .map_err(|source| BenchError::Codec {
                operation: "encode",
                payload: self.payload,
                source,
            })?;
        let lent = bytes::Bytes::from_owner(PooledBuffer {
            bytes: buffer,
            pool: Arc::clone(&self.pool),
        });
        self.publisher
            .put(ZBytes::from(lent))
            .wait()
            .map_err(|error| zenoh_error(TRANSPORT, "put", &self.key, error))?;
        self.next_seq += 1;
        Ok(MonotonicClock::read_ns().saturating_sub(publish_ns))
    }
}

/// Subscribes and decodes each sample into its own copy.
pub struct ZenohTcpReceiver<T: BenchMessage> {
    subscriber: Subscriber<FifoChannelHandler<Sample>>,
    mode: WakeMode,
    message: Box<T>,
    key: String,
    payload: &'static str,
    _session: Session,
}

impl<T: BenchMessage> ZenohTcpReceiver<T> {
    /// Listens on `endpoint` (see [`super::zenoh_link::free_loopback_endpoint`]) and subscribes.
    pub fn listen(
        endpoint: &str,
        mode: WakeMode,
        payload: &'static str,
    ) -> Result<Self, BenchError> {
        let key = key_expr(payload);
        let session = open_session(TRANSPORT, LinkEnd::Listen(endpoint))?;
        let subscriber = declare_subscriber(&session, TRANSPORT, &key)?;
        Ok(Self {
            subscriber,
            mode,
            message: zeroed_box(),
            key,
            payload,
            _session: session,
        })
    }
}

impl<T: BenchMessage> ReceivePort<T> for ZenohTcpReceiver<T> {
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError> {
        let Self {
            subscriber,
            mode,
            message,
            key,
            payload,
            ..
        } = self;
        let payload = *payload;
        receive_loop(subscriber, *mode, watchdog, TRANSPORT, key, |sample, _| {
            // Borrowed when Zenoh delivers the message in one piece, else gathered into a copy.
            let bytes = sample.payload().to_bytes();
            T::decode_into(&bytes, message).map_err(|source| BenchError::Codec {
                operation: "decode",
                payload,
                source,
            })?;
            on_message(message, MonotonicClock::read_ns())
        })
    }
}
