//! Emergency stop: every arm stops and every valve closes while engaged.

use crate::fixed_string::FixedString;
use crate::header::Header;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// The state of the emergency stop, latched on `safety/emergency_stop` (writer: the executive).
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.EmergencyStop.v1")]
pub struct EmergencyStop {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// 1 engaged, 0 released.
    pub engaged: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 7],
    /// Why it was engaged or released, for people.
    pub reason: FixedString<64>,
}
