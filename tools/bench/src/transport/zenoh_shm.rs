//! Zenoh with its shared-memory transport: the sender allocates each message from a Zenoh SHM
//! provider (a POSIX shared-memory pool of its own), writes it in place and publishes the
//! buffer; Zenoh sends only a descriptor over the loopback TCP link and the receiver reads the
//! message in place from the mapped segment. A payload that arrives as bytes over the link
//! instead (shared memory not negotiated) fails the run rather than measuring the wrong thing.

use super::zenoh_link::{
    LinkEnd, declare_publisher, declare_subscriber, key_expr, message_in_place,
    message_in_place_mut, open_session, receive_loop, wait_for_subscriber, zenoh_error,
};
use super::{OnMessage, ReceivePort, SendPort};
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::{Transport, WakeMode};
use crate::peer::stream_window;
use crate::sender_write::PayloadWriter;
use crate::watchdog::Watchdog;
use harvest_ipc::MonotonicClock;
use std::marker::PhantomData;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;
use zenoh::shm::{
    AllocAlignment, BlockOn, GarbageCollect, MemoryLayout, PosixShmProviderBackend, ShmProvider,
    ShmProviderBuilder,
};
use zenoh::{Session, Wait};

const TRANSPORT: Transport = Transport::ZenohShm;
/// Rounding of each message in the provider's pool (room for the allocator's alignment).
const PAGE_BYTES: usize = 4096;

/// Bytes of the sender's pool: the stream window plus two messages (the one being written and
/// the one the receiver may still hold), each rounded up to a page.
fn pool_bytes<T: BenchMessage>() -> usize {
    let message = std::mem::size_of::<T>().div_ceil(PAGE_BYTES) * PAGE_BYTES;
    (stream_window::<T>() + 2) * message + 16 * PAGE_BYTES
}

/// Allocates from its SHM provider, writes in place, publishes the buffer.
pub struct ZenohShmSender<T: BenchMessage> {
    publisher: Publisher<'static>,
    provider: ShmProvider<PosixShmProviderBackend>,
    layout: MemoryLayout,
    key: String,
    next_seq: u64,
    _session: Session,
    _message: PhantomData<T>,
}

impl<T: BenchMessage> ZenohShmSender<T> {
    /// Connects to the receiver at `endpoint` and waits until its subscriber is matched.
    pub fn connect(endpoint: &str, payload: &'static str) -> Result<Self, BenchError> {
        let key = key_expr(payload);
        let session = open_session(TRANSPORT, LinkEnd::Connect(endpoint))?;
        // The pool's alignment is the message's: the provider refuses allocations aligned
        // more strictly than its pool.
        let provider = ShmProviderBuilder::default_backend((
            pool_bytes::<T>(),
            AllocAlignment::for_type::<T>(),
        ))
        .wait()
        .map_err(|error| zenoh_error(TRANSPORT, "create the SHM provider", &key, error))?;
        let publisher = declare_publisher(&session, TRANSPORT, &key)?;
        wait_for_subscriber(&publisher, TRANSPORT, &key)?;
        Ok(Self {
            publisher,
            provider,
            layout: MemoryLayout::for_type::<T>(),
            key,
            next_seq: 1,
            _session: session,
            _message: PhantomData,
        })
    }
}

impl<T: BenchMessage> SendPort<T> for ZenohShmSender<T> {
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError> {
        let msg_seq = self.next_seq;
        // Blocks until a buffer is free (the receiver dropped an earlier sample).
        let mut buffer = self
            .provider
            .alloc(self.layout)
            .with_policy::<BlockOn<GarbageCollect>>()
            .wait()
            .map_err(|error| zenoh_error(TRANSPORT, "allocate", &self.key, format!("{error:?}")))?;
        let message = message_in_place_mut::<T>(&mut buffer).ok_or_else(|| {
            zenoh_error(
                TRANSPORT,
                "allocate",
                &self.key,
                "the provider returned a buffer of the wrong size or alignment",
            )
        })?;
        let publish_ns = writer.write_stamped(message, msg_seq, phase);
        self.publisher
            .put(buffer)
            .wait()
            .map_err(|error| zenoh_error(TRANSPORT, "put", &self.key, error))?;
        self.next_seq += 1;
        Ok(MonotonicClock::read_ns().saturating_sub(publish_ns))
    }
}

/// Subscribes and reads each message in place from shared memory.
pub struct ZenohShmReceiver<T: BenchMessage> {
    subscriber: Subscriber<FifoChannelHandler<Sample>>,
    mode: WakeMode,
    key: String,
    payload: &'static str,
    _session: Session,
    _message: PhantomData<T>,
}

impl<T: BenchMessage> ZenohShmReceiver<T> {
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
            key,
            payload,
            _session: session,
            _message: PhantomData,
        })
    }
}

impl<T: BenchMessage> ReceivePort<T> for ZenohShmReceiver<T> {
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError> {
        let (key, payload) = (self.key.as_str(), self.payload);
        receive_loop(
            &self.subscriber,
            self.mode,
            watchdog,
            TRANSPORT,
            key,
            |sample, recv_ns| {
                let Some(shm) = sample.payload().as_shm() else {
                    return Err(zenoh_error(
                        TRANSPORT,
                        "receive",
                        key,
                        format!(
                            "a {payload} message of {} bytes arrived over the link, not in \
shared memory (SHM was not negotiated)",
                            sample.payload().len()
                        ),
                    ));
                };
                let message = message_in_place::<T>(shm).ok_or_else(|| {
                    zenoh_error(
                        TRANSPORT,
                        "receive",
                        key,
                        format!(
                            "{} bytes at {:p} do not hold one aligned {payload} message ({} bytes)",
                            shm.len(),
                            shm.as_ptr(),
                            std::mem::size_of::<T>()
                        ),
                    )
                })?;
                on_message(message, recv_ns)
            },
        )
    }
}
