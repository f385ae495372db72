//! The header every payload starts with. One convention for the whole stack.

use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Per-message envelope.
///
/// - `msg_seq`: per-publisher sequence number, starting at 1 and incremented by the transport on
///   every send; a gap seen by a subscriber means dropped messages.
/// - `capture_ns`: time of validity of the data, stamped by the producer from the device's capture
///   time (camera exposure, encoder read), or the time the decision was made for commands.
/// - `publish_ns`: stamped by the transport right before the sample is handed to iceoryx2.
///
/// Both stamps are on the stack clock (see [`crate::clock`]).
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Describe,
)]
#[type_name("harvest.Header.v1")]
pub struct Header {
    /// Per-publisher sequence number, from 1; set by the transport.
    pub msg_seq: u64,
    /// Time of validity of the data, ns on the stack clock; set by the producer.
    pub capture_ns: u64,
    /// When the transport handed the sample to iceoryx2, ns on the stack clock.
    pub publish_ns: u64,
}
