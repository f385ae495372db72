//! The shared vacuum: arms request valve changes, the vacuum supervisor grants or refuses them
//! and reports the valves and pressures. Valves 1-2 serve arm 1, valves 3-4 serve arm 2; pressure
//! sensors: inside arm 1, inside arm 2, at the source.

use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Valves of the vacuum system: 1-2 serve arm 1, 3-4 serve arm 2.
pub const VALVE_COUNT: usize = 4;
/// Pressure sensors: inside arm 1, inside arm 2, at the source.
pub const PRESSURE_SENSOR_COUNT: usize = 3;

/// What an arm asks of its valves (code in [`ValveRequest::kind`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum ValveRequestKind {
    /// Open to attempt attachment.
    OpenForAttach = 1,
    /// Close (release at the drop-off, or abort).
    Close = 2,
}

/// What the vacuum supervisor infers from the pressure in one arm's end-effector (code in
/// [`VacuumState::arm_attachment`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum ArmAttachment {
    /// The arm's valve is closed.
    Closed = 0,
    /// The valve is open and air streams in: no seal (also after a failed attach or a drop).
    Open = 1,
    /// The valve is open and an apple seals the cup: attached.
    Sealed = 2,
}

/// The valve coordination policy the vacuum supervisor runs (code in [`VacuumState::policy`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum VacuumPolicyCode {
    /// One arm at a time.
    Baseline = 0,
    /// The 2023 staggered policy.
    Policy2023 = 1,
    /// The 2024 failure-aware policy.
    Policy2024 = 2,
}

/// An arm's request to open or close its valves (`vacuum/valve_request`).
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
#[type_name("harvest.ValveRequest.v1")]
pub struct ValveRequest {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The requesting arm, 1 or 2.
    pub arm_id: u8,
    /// What the arm asks.
    pub kind: WireCode<ValveRequestKind>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// Chosen by the arm; echoed in the [`ValveGrant`].
    pub request_seq: u32,
}

/// The vacuum supervisor's answer to one [`ValveRequest`] (`vacuum/valve_grant`).
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
#[type_name("harvest.ValveGrant.v1")]
pub struct ValveGrant {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The arm the answer is for, 1 or 2.
    pub arm_id: u8,
    /// 1 granted, 0 refused.
    pub granted: u8,
    /// Policy-specific reason code when refused (0 = none).
    pub reason: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: u8,
    /// The request's `request_seq`.
    pub request_seq: u32,
}

/// The vacuum system as the vacuum supervisor sees it (`vacuum/state`).
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
#[type_name("harvest.VacuumState.v1")]
pub struct VacuumState {
    /// `capture_ns` is when the valve board sampled; see [`Header`].
    pub header: Header,
    /// 1 open, 0 closed, per valve 1..4.
    pub valve_open: [u8; VALVE_COUNT],
    /// 1 while a valve is moving (butterfly valves take up to 1 s).
    pub valve_in_transit: [u8; VALVE_COUNT],
    /// Vacuum in mmH2O (positive = below atmosphere): arm 1, arm 2, source.
    pub pressure_mmh2o: [f32; PRESSURE_SENSOR_COUNT],
    /// Inferred per arm (arm 1, arm 2).
    pub arm_attachment: [WireCode<ArmAttachment>; 2],
    /// Active policy.
    pub policy: WireCode<VacuumPolicyCode>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: u8,
}
