//! The transports, each as a sending port (peer process) and a receiving port (the measuring
//! process), in both wake-up modes: ours, raw iceoryx2 and the copying socket always; the Zenoh
//! peers with the `zenoh` feature, Cyclone DDS with the `cyclonedds` feature.

pub mod copy;
#[cfg(feature = "cyclonedds")]
pub mod cyclonedds;
#[cfg(feature = "cyclonedds")]
pub mod cyclonedds_ffi;
pub mod ours;
pub mod raw;
#[cfg(feature = "zenoh")]
pub mod zenoh_link;
#[cfg(feature = "zenoh")]
pub mod zenoh_shm;
#[cfg(feature = "zenoh")]
pub mod zenoh_tcp;

use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::sender_write::PayloadWriter;
use crate::watchdog::Watchdog;
use harvest_ipc::Flow;

/// Called once per received message with the message (in shared memory for the zero-copy
/// transports) and its receive time in `CLOCK_MONOTONIC` nanoseconds.
pub type OnMessage<'a, T> = dyn FnMut(&T, u64) -> Result<Flow, BenchError> + 'a;

/// The sending side of a transport.
pub trait SendPort<T: BenchMessage> {
    /// Writes a fresh message of `phase` with `writer` (the fair test: every line of its body)
    /// and sends it. Stamps `capture_ns` before writing and `publish_ns` right before handing
    /// it to the transport. Returns the nanoseconds spent in the transport's send call from
    /// about `publish_ns` until it returned (sender side of the one-way latency).
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError>;
}

/// The receiving side of a transport.
pub trait ReceivePort<T: BenchMessage> {
    /// Receives messages (sleeping or spinning, by mode) and hands each to `on_message` until it
    /// returns [`Flow::Stop`]. Checks `watchdog` whenever nothing arrives for a while.
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError>;
}
