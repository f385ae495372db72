//! ALACS unit: red line laser on a 20 cm linear slide plus an RGB camera ([alacs sec. 3]).
//!
//! - [`AlacsUnit`]: the device trait every implementation provides.
//! - [`extrinsics`]: the laser-camera extrinsics `(alpha, L0, beta)`, the slide stroke and the
//!   laser plane as a function of the slide position ([alacs eq. 4-8]).
//! - [`conformance`]: the behaviour every implementation must show, generic over the trait.
//! - [`camera`]: the default ALACS camera intrinsics.
//! - [`mounting`]: where the unit sits relative to the ToF camera (`alacs_from_tof_camera`).
//! - [`sim`]: the driver of the simulated unit over the `hw/alacs/*` channels.

pub mod camera;
#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod error;
pub mod extrinsics;
pub mod mounting;
pub mod sim;

pub use camera::alacs_camera_intrinsics;
pub use error::{AlacsError, AlacsPart};
pub use extrinsics::{AlacsExtrinsics, LaserPlane, SLIDE_STROKE_M, check_slide_position};
pub use mounting::ALACS_FROM_TOF_CAMERA;
pub use sim::SimAlacsUnit;

use harvest_ipc::camera_model::CameraIntrinsics;

use crate::error_kind::DeviceError;

/// What came with one captured image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlacsFrameInfo {
    /// Capture time (time of validity), nanoseconds on the implementation's clock.
    pub stamp_ns: u64,
    /// Intrinsics of the camera that took the image (the buffer is `width x height x 3`).
    pub intrinsics: CameraIntrinsics,
    /// Slide position measured by the slide's encoder while the image was taken, m.
    pub slide_position_m: f64,
    /// Whether the laser was on during the exposure.
    pub laser_on: bool,
}

/// An ALACS unit: a line laser on a linear slide and an RGB camera fixed to the slide's frame.
///
/// Meant for a single-threaded scan loop: every method takes `&mut self`, blocks for one bounded
/// exchange and returns.
///
/// Physical caveats every caller must respect:
/// - **Stroke.** The slide position `d` (m from the home end, moving the laser towards the
///   camera, so `L = L0 - d`) must be in `[0, SLIDE_STROKE_M]`; anything else (or NaN) fails
///   with kind `InvalidRequest` without moving.
/// - **Settling.** [`AlacsUnit::move_slide`] returns once the slide has settled and reports the
///   encoder position, which differs from the request by the encoder resolution and the
///   positioning error; triangulate with the *returned* position, not the requested one.
/// - **Exposure.** An image shows the laser only if it was on for the whole exposure; switch it
///   before capturing, not during.
/// - **Eye safety.** The laser stays on until switched off; switch it off when a scan ends or
///   fails.
pub trait AlacsUnit {
    /// The implementation's error; its [`DeviceError::kind`] is what generic code reacts to.
    type Error: DeviceError;

    /// Intrinsics of the unit's camera (fixed for the unit's life).
    fn intrinsics(&self) -> CameraIntrinsics;

    /// Moves the slide to `slide_position_m`, blocks until it settled, and returns the position
    /// the encoder measured, m.
    fn move_slide(&mut self, slide_position_m: f64) -> Result<f64, Self::Error>;

    /// Switches the laser on or off. Idempotent.
    fn set_laser(&mut self, on: bool) -> Result<(), Self::Error>;

    /// Captures one RGB8 image (row-major, `width x height x 3` bytes) into `rgb`.
    /// A buffer of another size fails with kind `InvalidRequest` and is left untouched.
    fn capture_rgb(&mut self, rgb: &mut [u8]) -> Result<AlacsFrameInfo, Self::Error>;
}
