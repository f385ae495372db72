//! The frame camera: the ToF RGB-D camera ([`sim`], served by the simulator) or a GigE Vision
//! colour camera ([`gige`], through Aravis), whose frames carry no depth of their own
//! (`RgbdFrameMeta::FLAG_COLOR_ONLY`: perception takes depth from the LiDAR).
//!
//! ToF RGB-D camera (Percipio TL460-S1-E1): colour 1920x1080, depth 640x480 in mm, range
//! 0.3-9.5 m, field of view 62 x 49 deg, depth accuracy +/-(4 mm + 0.25 % of depth).
//!
//! Physical caveats: depth is measured by time of flight and degrades in direct sunlight
//! (missing returns, noise); the colour image saturates when the sun is in view; depth and colour
//! come from two sensors a few centimetres apart, related by the registration in the frame's
//! metadata. Frames free-run at the device's rate; the capture time is the device's.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod gige;
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

    /// The link's counters since the camera was opened (all 0 for a camera that cannot lose
    /// frames, such as the simulated one).
    fn health(&self) -> CameraHealth {
        CameraHealth::default()
    }
}

/// What a camera driver counts about its link, for the health heartbeat.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CameraHealth {
    /// Frames delivered.
    pub frames: u64,
    /// Frames the camera sent that were not delivered (incomplete, or never arrived).
    pub lost_frames: u64,
    /// Packets the camera sent again on request.
    pub resent_packets: u64,
    /// Packets that never arrived, even after resend requests.
    pub missing_packets: u64,
    /// Frames that found no free buffer on the host.
    pub underruns: u64,
}
