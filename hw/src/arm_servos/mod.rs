//! The servo joints of one 4-DOF tube arm: prismatic D (m), revolute theta and phi (rad), and the
//! end-effector rotation (twist, rad), with encoder feedback.
//!
//! Physical caveats: servos follow set-points with a lag (first order, tens of milliseconds);
//! set-points outside the joint limits of [dual-arm Table 1] are refused by the driver, never sent; the
//! encoders are sampled by the servo controller at its own rate, so feedback carries the
//! controller's capture time. Commands are expected at >= 200 Hz; a servo controller that stops
//! receiving them holds position.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
#[cfg(any(test, feature = "testing"))]
pub mod double;
pub mod sim;

use crate::error_kind::DeviceError;

/// Joint order everywhere: `[D m, theta rad, phi rad, twist rad]`.
pub const JOINT_COUNT: usize = 4;

/// Encoder feedback of one arm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointFeedback {
    /// When the servo controller sampled the encoders (stack clock).
    pub capture_ns: u64,
    /// Joint positions: D in m, theta/phi/twist in rad.
    pub position: [f64; JOINT_COUNT],
    /// Joint velocities: m/s for D, rad/s for the others.
    pub velocity: [f64; JOINT_COUNT],
    /// Bit per joint: the servo reports a fault.
    pub fault_bits: u8,
}

/// One arm's servos.
pub trait ArmServos {
    /// The driver's error; its kind tells a refused set-point from a lost link.
    type Error: DeviceError;

    /// Sends position set-points with feed-forward velocities. Fails with kind `InvalidRequest`
    /// (nothing sent) for non-finite values or positions outside the joint limits.
    fn command(
        &mut self,
        position: [f64; JOINT_COUNT],
        velocity: [f64; JOINT_COUNT],
    ) -> Result<(), Self::Error>;

    /// Brake: hold the current position.
    fn hold(&mut self) -> Result<(), Self::Error>;

    /// The newest encoder feedback; `None` before the first sample arrived.
    fn feedback(&mut self) -> Result<Option<JointFeedback>, Self::Error>;
}
