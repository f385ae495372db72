//! The mobile platform's positioning stages: in-out (toward the canopy) and up-down, with
//! position feedback ([dual-arm sec. 2]: two stepper motors behind an Arduino Uno that
//! reports the positions to the main computer). The robot moves them between harvesting zones,
//! never while an arm picks.
//!
//! Physical caveats: the stages are slow (centimetres per second) and settle before they
//! report `in_motion = false`; positions are from encoders on the stages, sampled by the
//! controller at its own rate, so feedback carries the controller's capture time. A target is
//! accepted when the command is sent, not when the stages arrive: poll [`Platform::position`]
//! until `in_motion` is false.
//!
//! - [`Platform`]: the device trait; [`PlatformTravel`]: the stages' travel limits.
//! - [`sim`]: the driver of the simulated platform over `hw/platform/*`.
//! - [`conformance`]: the behaviour every implementation must show.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod sim;
pub mod travel;

pub use travel::{PlatformAxis, PlatformTravel};

use crate::error_kind::DeviceError;

/// Where the platform stands.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlatformPosition {
    /// When the controller sampled the stage encoders (stack clock).
    pub capture_ns: u64,
    /// Toward the canopy, metres from the home stop.
    pub in_out_m: f64,
    /// Up from the lowest stop, metres.
    pub up_down_m: f64,
    /// True while either stage moves, or a command was sent that the controller has not acted
    /// on yet.
    pub in_motion: bool,
}

/// The platform movement module.
pub trait Platform {
    /// The driver's error; its kind tells a refused target from a stage fault or a lost device.
    type Error: DeviceError;

    /// The travel the stages accept; targets outside it are refused.
    fn travel(&self) -> PlatformTravel;

    /// Starts moving both stages to the given position. Returns once the command is sent.
    /// Targets outside [`Platform::travel`] or not finite fail with kind `InvalidRequest`
    /// (nothing sent, the stages keep their previous target).
    fn move_to(&mut self, in_out_m: f64, up_down_m: f64) -> Result<(), Self::Error>;

    /// Stops both stages where they are (they decelerate, then report `in_motion = false`).
    fn stop(&mut self) -> Result<(), Self::Error>;

    /// Current position and whether the stages are still moving.
    fn position(&mut self) -> Result<PlatformPosition, Self::Error>;
}
