//! The mobile platform's positioning stages: in-out (toward the canopy) and up-down, with
//! position feedback. The robot moves them between harvesting zones, never while an arm picks.
//!
//! Physical caveats: the stages are slow (centimetres per second) and settle before they
//! report `in_motion = false`; positions are from linear encoders on the stages.

use crate::error_kind::DeviceError;

/// Where the platform stands.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlatformPosition {
    pub capture_ns: u64,
    /// Toward the canopy, metres from the home stop.
    pub in_out_m: f64,
    /// Up from the lowest stop, metres.
    pub up_down_m: f64,
    pub in_motion: bool,
}

pub trait Platform {
    type Error: DeviceError;

    /// Starts moving both stages to the given position (out-of-range targets: `InvalidRequest`).
    fn move_to(&mut self, in_out_m: f64, up_down_m: f64) -> Result<(), Self::Error>;

    /// Current position and whether the stages are still moving.
    fn position(&mut self) -> Result<PlatformPosition, Self::Error>;
}
