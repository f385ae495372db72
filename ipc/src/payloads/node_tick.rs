//! What one tick of a control node saw (`arm1/ticks`, `arm2/ticks`, `vacuum/ticks`): the stop
//! and the mode it heard, what its devices answered, and which messages it read, so that a
//! recording holds everything the node decided from and `harvest replay --check` can re-run it.

use crate::bounded_vec::BoundedVec;
use crate::header::Header;
use crate::payloads::DeviceErrorCode;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Input messages one record names; a tick that read more says so
/// ([`NodeTickRecord::inputs_complete`] = 0).
pub const TICK_INPUTS: usize = 24;
/// Bytes of device readings one record holds (the readings encoded by the codec).
pub const TICK_READINGS_BYTES: usize = 160;
/// [`TickInput::slot`] of the `operator/mode` sample the runner read (not a node input).
pub const MODE_SLOT: u8 = u8::MAX;

/// What the emergency-stop channel said at a tick (code in
/// [`NodeTickRecord::emergency_stop_heard`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum StopHeard {
    /// No new sample.
    Nothing = 0,
    /// A sample saying released.
    Released = 1,
    /// A sample saying engaged.
    Engaged = 2,
}

/// What the device read of a tick gave (code in [`NodeTickRecord::device_read`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum DeviceRead {
    /// Readings, in [`NodeTickRecord::readings`].
    Readings = 0,
    /// The device had nothing yet.
    Nothing = 1,
    /// The read failed ([`NodeTickRecord::read_error`] says how).
    Failed = 2,
    /// The device answered with readings that do not fit the record (more than
    /// [`TICK_READINGS_BYTES`] encoded): the tick cannot be re-run.
    TooLarge = 3,
}

/// One message a node read at a tick: which input slot (in the order the node visits them;
/// [`MODE_SLOT`] for the operator's mode) and the message's own stamps, by which it is found in
/// a recording.
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
    crate::Describe,
)]
pub struct TickInput {
    /// The message's `header.msg_seq`.
    pub msg_seq: u64,
    /// The message's `header.publish_ns`.
    pub publish_ns: u64,
    /// The node's input slot, from 0 in visiting order; [`MODE_SLOT`]: `operator/mode`.
    pub slot: u8,
    /// Zero; keeps the record aligned.
    pub _reserved: [u8; 7],
}

/// One tick of a control node, as its runner saw it (see the module documentation).
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
#[type_name("harvest.NodeTickRecord.v1")]
pub struct NodeTickRecord {
    /// `capture_ns` is the tick's time (what the node was told `now` is); see [`Header`].
    pub header: Header,
    /// The tick's number since the process started, from 1 (1 again after a restart).
    pub tick: u64,
    /// The stop sample read at this tick, if any.
    pub emergency_stop_heard: WireCode<StopHeard>,
    /// What the device read gave.
    pub device_read: WireCode<DeviceRead>,
    /// The read's error kind when it failed (`None` otherwise).
    pub read_error: WireCode<DeviceErrorCode>,
    /// The kind of error with which the device refused the tick's commands (`None`: written,
    /// or not written because the devices were made safe).
    pub write_error: WireCode<DeviceErrorCode>,
    /// 1: the node runs without an operator (takes up work before a mode is heard).
    pub without_operator: u8,
    /// 1: every message read is in [`Self::inputs`]; 0: more than [`TICK_INPUTS`] were read.
    pub inputs_complete: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// The device readings, encoded by the codec (empty unless `device_read` is readings).
    pub readings: BoundedVec<u8, TICK_READINGS_BYTES>,
    /// The messages read, slot by slot in visiting order, oldest first within a slot.
    pub inputs: BoundedVec<TickInput, TICK_INPUTS>,
}
