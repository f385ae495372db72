//! Hardware-layer messages: what device drivers exchange with their devices (the simulator
//! serves them in simulation; a bridge to a real bus could serve them on the robot).

use crate::bounded_vec::BoundedVec;
use crate::header::Header;
use crate::payloads::arm::JOINT_COUNT;
use crate::payloads::vacuum::{PRESSURE_SENSOR_COUNT, VALVE_COUNT};
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Servo set-points sent to one arm's joint servos (driver -> device).
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
#[type_name("harvest.ServoSetpoint.v1")]
pub struct ServoSetpoint {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// 1: hold position (brake), 0: track.
    pub hold: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 7],
    /// D in m, theta/phi/twist in rad.
    pub joint_position: [f64; JOINT_COUNT],
    /// Feed-forward velocities, m/s and rad/s.
    pub joint_velocity: [f64; JOINT_COUNT],
}

/// Encoder feedback of one arm (device -> driver), at the servo rate.
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
#[type_name("harvest.EncoderFeedback.v1")]
pub struct EncoderFeedback {
    /// `capture_ns` is when the encoders were read; see [`Header`].
    pub header: Header,
    /// Measured joint positions: D in m, theta/phi/twist in rad.
    pub joint_position: [f64; JOINT_COUNT],
    /// Measured joint velocities: m/s for D, rad/s for the others.
    pub joint_velocity: [f64; JOINT_COUNT],
    /// Bit per joint: fault (over-current, limit switch).
    pub fault_bits: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 7],
}

/// Valve commands to the valve board (driver -> device).
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
#[type_name("harvest.ValveBoardCommand.v1")]
pub struct ValveBoardCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// 1 open, 0 closed, valves 1..4.
    pub valve_open: [u8; VALVE_COUNT],
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 4],
}

/// Valve and pressure readings of the valve board (device -> driver).
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
#[type_name("harvest.ValveBoardReadings.v1")]
pub struct ValveBoardReadings {
    /// `capture_ns` is when the board sampled; see [`Header`].
    pub header: Header,
    /// 1 open, 0 closed, valves 1..4 (valves 1-2 arm 1, 3-4 arm 2).
    pub valve_open: [u8; VALVE_COUNT],
    /// 1 while a valve is moving between its end positions.
    pub valve_in_transit: [u8; VALVE_COUNT],
    /// Vacuum in mmH2O: inside arm 1, inside arm 2, at the source.
    pub pressure_mmh2o: [f32; PRESSURE_SENSOR_COUNT],
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 4],
}

/// At most this many apples in the ground truth message.
pub const MAX_TRUE_APPLES: usize = 256;

/// Where a true apple is (code in [`TrueApple::state`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum TrueAppleState {
    /// Still on the tree.
    OnTree = 0,
    /// Held by arm 1's end-effector.
    OnArm1 = 1,
    /// Held by arm 2's end-effector.
    OnArm2 = 2,
    /// Fell (knocked off, released away from the dropping module).
    Dropped = 3,
    /// Released onto the dropping module.
    Harvested = 4,
}

/// One apple as the simulator knows it.
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
pub struct TrueApple {
    /// The simulator's id of the apple.
    pub apple_id: u32,
    /// Where the apple is.
    pub state: WireCode<TrueAppleState>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 3],
    /// True centre in the robot frame, metres.
    pub center_in_robot_m: [f64; 3],
    /// True radius, metres.
    pub radius_m: f64,
}

/// Evaluation only: the true apples. No stack process may subscribe.
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
#[type_name("harvest.GroundTruth.v1")]
pub struct GroundTruth {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// Every apple of the scene.
    pub apples: BoundedVec<TrueApple, MAX_TRUE_APPLES>,
}
