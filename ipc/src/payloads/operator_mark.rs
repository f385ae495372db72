//! An operator's mark: a note that something worth looking at happened now (`harvest ctl mark
//! "text"`, the console). The recorder files a clip of its flight recorder around each mark and
//! lists the mark in the recording's events. A mark commands nothing, so it needs no control
//! token.

use crate::fixed_string::FixedString;
use crate::header::Header;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Capacity of [`OperatorMark::text`], bytes.
pub const MARK_TEXT_BYTES: usize = 120;
/// Capacity of [`OperatorMark::source`], bytes.
pub const MARK_SOURCE_BYTES: usize = 32;

/// One mark (`operator/mark`). `header.capture_ns` is when the operator made it.
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
#[type_name("harvest.OperatorMark.v1")]
pub struct OperatorMark {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// What the operator wrote (cut at [`MARK_TEXT_BYTES`]).
    pub text: FixedString<MARK_TEXT_BYTES>,
    /// Who made it: `ctl`, `console`, ...
    pub source: FixedString<MARK_SOURCE_BYTES>,
}
