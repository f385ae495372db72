//! The tractor pulling the robot's trailer along the orchard row ([dual-arm sec. 2.2, 4.1]:
//! the robot harvests stop and go; the tractor halts at a harvest location and advances
//! to the next when the robot is done).
//!
//! Positions are metres along the row from its start. A target is accepted when the command is
//! sent, not when the trailer arrives: poll [`Tractor::position`] until `in_motion` is false.
//! The tractor only drives forward, and not past the end of the row.
//!
//! - [`Tractor`]: the device trait;
//! - [`sim`]: the driver of the simulated tractor over `hw/tractor/*`;
//! - [`conformance`]: the behaviour every implementation must show.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod sim;

use crate::error_kind::DeviceError;

/// Where the trailer stands.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TractorPosition {
    /// When the position was sampled (stack clock).
    pub capture_ns: u64,
    /// Metres along the row.
    pub position_m: f64,
    /// The end of the row, m (targets beyond it are refused).
    pub row_end_m: f64,
    /// True while the tractor moves, or a command was sent that it has not acted on yet.
    pub in_motion: bool,
}

/// The tractor, as the robot commands it.
pub trait Tractor {
    /// The driver's error; its kind tells a refused advance from a silent tractor.
    type Error: DeviceError;

    /// Starts driving forward by `distance_m` from the current position (at the tractor's
    /// speed). Returns once the command is sent. A distance that is negative, not finite or
    /// past the end of the row fails with kind `InvalidRequest` (nothing sent).
    fn advance(&mut self, distance_m: f64) -> Result<(), Self::Error>;

    /// Stops where it is.
    fn stop(&mut self) -> Result<(), Self::Error>;

    /// Current position and whether the tractor is still moving.
    fn position(&mut self) -> Result<TractorPosition, Self::Error>;
}
