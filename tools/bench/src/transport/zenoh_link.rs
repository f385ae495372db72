//! What the two Zenoh peer transports share: the sessions (peer mode, one loopback TCP link from
//! the sender to the receiver's listener, no scouting), the key expression, the publisher's
//! QoS, waiting until the publisher sees the subscriber, the receive loop in both wake-up modes,
//! and reading a message in place from received bytes.
//!
//! Event mode blocks in the subscriber's FIFO handler (`recv_timeout`: Zenoh's subscriber
//! callback pushes each sample into it); poll mode spins on `try_recv`.

use crate::error::BenchError;
use crate::options::{Transport, WakeMode};
use crate::watchdog::{WATCH_PERIOD, Watchdog};
use harvest_ipc::{Flow, MonotonicClock, Payload};
use std::time::{Duration, Instant};
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;
use zenoh::{Config, Session, Wait};

/// How long the sender waits for the receiver's subscriber to become visible.
const MATCH_TIMEOUT: Duration = Duration::from_secs(10);

/// The key expression a payload's messages are published on.
pub fn key_expr(payload: &'static str) -> String {
    format!("harvest/bench/{payload}")
}

/// A failed Zenoh call of `transport` on `key`.
pub fn zenoh_error(
    transport: Transport,
    operation: &'static str,
    key: &str,
    reason: impl std::fmt::Display,
) -> BenchError {
    BenchError::PeerTransport {
        transport: transport.name(),
        operation,
        key: key.to_owned(),
        reason: reason.to_string(),
    }
}

/// A loopback TCP endpoint for the receiver's listener, on a port the kernel just handed out
/// to a throw-away socket (should another process take it first, Zenoh fails naming it).
pub fn free_loopback_endpoint(transport: Transport) -> Result<String, BenchError> {
    let listener = std::net::TcpListener::bind(("127.0.0.1", 0))
        .map_err(|error| zenoh_error(transport, "pick a loopback port", "127.0.0.1:0", error))?;
    let port = listener
        .local_addr()
        .map_err(|error| zenoh_error(transport, "pick a loopback port", "127.0.0.1:0", error))?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

/// Which end of the link a session is.
#[derive(Debug, Clone, Copy)]
pub enum LinkEnd<'a> {
    /// The receiver: listens on the endpoint.
    Listen(&'a str),
    /// The sender: connects to the receiver's endpoint and listens nowhere.
    Connect(&'a str),
}

/// Opens a peer-mode session for `transport`: shared memory on for `zenoh-shm` (set up when the
/// session opens, not on the first message) and off for `zenoh-tcp`; the implicit copy of
/// large regular payloads into shared memory is off in both, so each transport is what it says.
pub fn open_session(transport: Transport, end: LinkEnd<'_>) -> Result<Session, BenchError> {
    let shm = transport == Transport::ZenohShm;
    let (listen, connect) = match end {
        LinkEnd::Listen(endpoint) => (format!("[\"{endpoint}\"]"), "[]".to_owned()),
        LinkEnd::Connect(endpoint) => ("[]".to_owned(), format!("[\"{endpoint}\"]")),
    };
    let settings = [
        ("mode", "\"peer\"".to_owned()),
        ("scouting/multicast/enabled", "false".to_owned()),
        ("listen/endpoints", listen),
        ("connect/endpoints", connect),
        ("transport/shared_memory/enabled", shm.to_string()),
        (
            "transport/shared_memory/mode",
            if shm { "\"init\"" } else { "\"lazy\"" }.to_owned(),
        ),
        (
            "transport/shared_memory/transport_optimization/enabled",
            "false".to_owned(),
        ),
    ];
    let mut config = Config::default();
    for (key, value) in settings {
        config
            .insert_json5(key, &value)
            .map_err(|error| zenoh_error(transport, "configure the session", key, error))?;
    }
    let endpoint = match end {
        LinkEnd::Listen(endpoint) | LinkEnd::Connect(endpoint) => endpoint,
    };
    zenoh::open(config)
        .wait()
        .map_err(|error| zenoh_error(transport, "open a session", endpoint, error))
}

/// Declares the publisher: reliable, blocking on congestion (a dropped message would stall the
/// stop-and-wait protocol) and express (sent at once, not batched: Zenoh's low-latency setting).
pub fn declare_publisher(
    session: &Session,
    transport: Transport,
    key: &str,
) -> Result<Publisher<'static>, BenchError> {
    session
        .declare_publisher(key.to_owned())
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(|error| zenoh_error(transport, "declare the publisher", key, error))
}

/// Declares the subscriber with Zenoh's default FIFO handler.
pub fn declare_subscriber(
    session: &Session,
    transport: Transport,
    key: &str,
) -> Result<Subscriber<FifoChannelHandler<Sample>>, BenchError> {
    session
        .declare_subscriber(key.to_owned())
        .wait()
        .map_err(|error| zenoh_error(transport, "declare the subscriber", key, error))
}

/// Waits until `publisher` sees a matching subscriber (the receiver's), so the first message is
/// not published before the subscriber's declaration reached this process.
pub fn wait_for_subscriber(
    publisher: &Publisher<'_>,
    transport: Transport,
    key: &str,
) -> Result<(), BenchError> {
    let start = Instant::now();
    loop {
        let status = publisher
            .matching_status()
            .wait()
            .map_err(|error| zenoh_error(transport, "read the matching status", key, error))?;
        if status.matching() {
            tracing::debug!(
                transport = transport.name(),
                key,
                waited_ms = start.elapsed().as_millis(),
                "subscriber matched"
            );
            return Ok(());
        }
        if start.elapsed() > MATCH_TIMEOUT {
            return Err(zenoh_error(
                transport,
                "wait for the receiver's subscriber",
                key,
                format!(
                    "no matching subscriber within {} s",
                    MATCH_TIMEOUT.as_secs()
                ),
            ));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Receives samples (blocking in event mode, spinning in poll mode) and hands each with its
/// receive time to `on_sample` until it returns [`Flow::Stop`]. Checks `watchdog` whenever
/// nothing arrives for a while.
pub fn receive_loop(
    subscriber: &Subscriber<FifoChannelHandler<Sample>>,
    mode: WakeMode,
    watchdog: &mut Watchdog,
    transport: Transport,
    key: &str,
    mut on_sample: impl FnMut(Sample, u64) -> Result<Flow, BenchError>,
) -> Result<(), BenchError> {
    loop {
        let next = match mode {
            WakeMode::Event => subscriber.recv_timeout(WATCH_PERIOD),
            WakeMode::Poll => subscriber.try_recv(),
        }
        .map_err(|error| zenoh_error(transport, "receive", key, error))?;
        match next {
            Some(sample) => {
                let recv_ns = MonotonicClock::read_ns();
                if on_sample(sample, recv_ns)? == Flow::Stop {
                    return Ok(());
                }
            }
            None => match mode {
                WakeMode::Event => watchdog.check()?,
                WakeMode::Poll => {
                    watchdog.poll_check()?;
                    std::hint::spin_loop();
                }
            },
        }
    }
}

/// `bytes` read in place as the message they hold, if they are exactly one aligned `T`.
pub fn message_in_place<T: Payload>(bytes: &[u8]) -> Option<&T> {
    let pointer = bytes.as_ptr().cast::<T>();
    if bytes.len() != std::mem::size_of::<T>() || !pointer.is_aligned() {
        return None;
    }
    // SAFETY: the bytes are initialized, exactly `size_of::<T>()` long and aligned for `T`
    // (checked above), and `T: Payload` is plain data for which every bit pattern is a valid
    // value. The borrow of `bytes` keeps them alive and unchanged for the reference's lifetime.
    Some(unsafe { &*pointer })
}

/// [`message_in_place`] for writing: the sender's message in a buffer it owns.
pub fn message_in_place_mut<T: Payload>(bytes: &mut [u8]) -> Option<&mut T> {
    let pointer = bytes.as_mut_ptr().cast::<T>();
    if bytes.len() != std::mem::size_of::<T>() || !pointer.is_aligned() {
        return None;
    }
    // SAFETY: as in `message_in_place`; the exclusive borrow of `bytes` makes this the only
    // access for the reference's lifetime.
    Some(unsafe { &mut *pointer })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench_payload::BenchPayload;

    #[test]
    fn in_place_reads_need_the_exact_size_and_alignment() {
        type Small = BenchPayload<32>;
        let mut words = vec![0u64; 9];
        let bytes: &mut [u8] = bytemuck_free_bytes(&mut words);
        assert!(message_in_place::<Small>(&bytes[..64]).is_some());
        assert!(message_in_place::<Small>(&bytes[..63]).is_none());
        assert!(message_in_place::<Small>(&bytes[1..65]).is_none());
        let message = message_in_place_mut::<Small>(&mut bytes[8..72]).expect("aligned");
        message.phase = 7;
        assert_eq!(
            message_in_place::<Small>(&bytes[8..72]).map(|m| m.phase),
            Some(7)
        );
    }

    /// The bytes of a `u64` buffer (8-aligned) without a helper crate.
    fn bytemuck_free_bytes(words: &mut [u64]) -> &mut [u8] {
        let len = std::mem::size_of_val(words);
        // SAFETY: u64s are plain bytes; the slice covers exactly the buffer it borrows.
        unsafe { std::slice::from_raw_parts_mut(words.as_mut_ptr().cast::<u8>(), len) }
    }
}
