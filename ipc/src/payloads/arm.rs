//! Per-arm channels: the target assigned to an arm, the joint commands sent to its servos, and
//! the state it reports.

use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Prismatic D (m), revolute theta (rad), revolute phi (rad), end-effector rotation (rad).
pub const JOINT_COUNT: usize = 4;

/// The four-phase picking cycle, plus idle and stopped (code in [`ArmState::phase`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum ArmPhase {
    /// No attempt running; waiting for a target.
    Idle = 0,
    /// Moving the end-effector to the apple.
    Approach = 1,
    /// Opening the vacuum and waiting for the seal at the apple.
    AttachDetach = 2,
    /// Pulling the apple back out of the canopy.
    Retract = 3,
    /// Releasing the apple at the drop-off.
    Release = 4,
    /// Stopped by the emergency stop or a fault; set-points hold.
    Stopped = 5,
}

/// What became of the newest target an arm received and has not taken up (code in
/// [`ArmState::target_status`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum TargetStatus {
    /// No target waiting (none received, or taken up: the attempt runs).
    None = 0,
    /// Refused for the moment (the other arm's swept path is in the way, stale feedback): the
    /// arm offers it to its picking cycle again every control tick.
    Waiting = 1,
    /// Refused for good (outside the workspace, not finite, stale detection) and dropped.
    Refused = 2,
}

/// An apple assigned to an arm (from assignment). A target with `apple_id` 0 withdraws the
/// target the arm has not taken up yet (its position is NaN, so an arm that predates
/// withdrawals refuses it as not finite, with the same effect); a running attempt goes on.
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
#[type_name("harvest.ArmTarget.v1")]
pub struct ArmTarget {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The arm the target is for, 1 or 2.
    pub arm_id: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 3],
    /// The vacuum supervisor's id of the apple (0 withdraws the waiting target).
    pub apple_id: u32,
    /// Apple centre in the robot frame, metres (NaN in a withdrawal).
    pub position_in_robot_m: [f64; 3],
    /// Apple radius, metres.
    pub radius_m: f64,
    /// `capture_ns` of the frame the position was measured in (staleness check).
    pub source_capture_ns: u64,
}

/// Joint set-points for one arm's servos (controller -> arm driver), sent every control period.
///
/// `header.capture_ns` is the control tick the command was computed at. `apple_id` and
/// `source_capture_ns` tie the command to the detection behind the arm's current target, so the
/// latency of the chain camera frame -> perception -> target -> command can be read from headers
/// alone (`source_capture_ns` is the camera frame's `capture_ns`).
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
#[type_name("harvest.ArmCommand.v2")]
pub struct ArmCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The arm commanded, 1 or 2.
    pub arm_id: u8,
    /// 1: hold (ignore set-points, brake), 0: track set-points.
    pub hold: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// The apple of the arm's current target (0: none).
    pub apple_id: u32,
    /// `capture_ns` of the camera frame whose detection set produced the current target (0 when
    /// the arm has no target).
    pub source_capture_ns: u64,
    /// D in m, theta/phi/twist in rad.
    pub joint_position: [f64; JOINT_COUNT],
    /// m/s and rad/s feed-forward velocities.
    pub joint_velocity: [f64; JOINT_COUNT],
}

/// What an arm reports at its control rate.
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
#[type_name("harvest.ArmState.v2")]
pub struct ArmState {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The reporting arm, 1 or 2.
    pub arm_id: u8,
    /// Where the arm is in its picking cycle.
    pub phase: WireCode<ArmPhase>,
    /// 1 when the arm believes it holds an apple (vacuum sealed).
    pub holding: u8,
    /// What became of the target `target_apple_id`, the newest one received and not taken up.
    pub target_status: WireCode<TargetStatus>,
    /// The apple of that target (`ArmTarget::apple_id`; 0 when `target_status` is
    /// [`TargetStatus::None`]).
    pub target_apple_id: u32,
    /// The apple of the running attempt (0: none).
    pub apple_id: u32,
    /// Apples this arm has released at the drop-off since the process started.
    pub harvested_count: u32,
    /// Encoder feedback: D in m, theta/phi/twist in rad.
    pub joint_position: [f64; JOINT_COUNT],
    /// Encoder feedback velocities: m/s for D, rad/s for the others.
    pub joint_velocity: [f64; JOINT_COUNT],
    /// End-effector (suction cup) position in the robot frame from the forward kinematics,
    /// metres.
    pub end_effector_in_robot_m: [f64; 3],
    /// Period of the last control cycle.
    pub control_period_ns: u64,
}
