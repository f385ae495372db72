//! ToF RGB-D camera (Percipio TL460-S1-E1): colour 1920x1080, depth 640x480 in mm, range
//! 0.3-9.5 m, field of view 62 x 49 deg, depth accuracy +/-(4 mm + 0.25 % of depth).
//!
//! Physical caveats: depth is measured by time of flight and degrades in direct sunlight
//! (missing returns, noise); the colour image saturates when the sun is in view; depth and colour
//! come from two sensors a few centimetres apart, related by the registration in the frame's
//! metadata. Frames free-run at the device's rate; the capture time is the device's.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod sim;

use crate::error_kind::DeviceError;
use harvest_ipc::payloads::RgbdFrame;
use std::time::Duration;

/// A frame source the camera process drives.
pub trait RgbdCamera {
    /// The driver's error; its kind tells a late frame from a lost camera.
    type Error: DeviceError;

    /// Blocks until the device's next frame or `timeout`, and writes the frame into `frame`
    /// (loaned shared memory): pixels, metadata and `header.capture_ns`. Returns `false` on
    /// timeout (nothing written).
    fn capture_into(
        &mut self,
        frame: &mut RgbdFrame,
        timeout: Duration,
    ) -> Result<bool, Self::Error>;
}
