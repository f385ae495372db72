//! Solid-state LiDAR (Livox Mid-70, [fusion Table II]): 70.4 deg circular field of
//! view, about 100,000 points/s, range error within 2 cm over 0.2-20 m, a return intensity per
//! point, and a non-repetitive rosette scan whose coverage of the field of view densifies the
//! longer the returns are integrated (the fusion paper integrates under 2 s for perception and 15 s for
//! calibration).
//!
//! Physical caveats: the two Risley prisms trace rosette petals, so the centre of the field is
//! sampled more densely than the rim; a point at a depth discontinuity can mix both surfaces
//! (beam divergence, the fusion paper's "bleeding points", not simulated); returns carry no colour:
//! colour comes from fusing with the camera (`harvest-lidar`).
//!
//! - [`spec`]: the Mid-70 parameters as constants and a typed configuration.
//! - [`mounting`]: the LiDAR frame convention and the CAD pose of the LiDAR on the camera.
//! - [`sim`]: the driver of the simulated device (frames on `hw/lidar/points`).
//! - [`livox`]: the driver of the real Mid-70 over the Livox SDK 1 protocol (UDP).
//! - [`health`]: what a driver reports about its device besides the clouds.
//! - [`conformance`]: the behaviour every implementation must show, generic over the trait.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod health;
pub mod livox;
pub mod mounting;
pub mod sim;
pub mod spec;

use crate::error_kind::DeviceError;
use harvest_ipc::payloads::PointCloud;
use std::time::Duration;

pub use health::{LidarCondition, LidarHealth};
pub use mounting::{CAD_CAMERA_FROM_LIDAR, OPTICAL_FROM_LIDAR};
pub use spec::LidarSpec;

/// An integrated point-cloud source the `lidar` process drives.
pub trait Lidar {
    /// The driver's error; its kind tells a refused setting from a lost device.
    type Error: DeviceError;

    /// Blocks until the device has delivered one integration window of returns or `timeout`,
    /// and writes the integrated cloud into `cloud` (loaned shared memory): points, metadata and
    /// `header.capture_ns` (end of the window, stack clock). Returns `false` on timeout: the
    /// returns received so far are kept for the next call, either by the driver or in `cloud`
    /// itself, so after `false` (or an error) the caller passes the same cloud again (the
    /// `lidar` process keeps its loan); after `true` any cloud may follow.
    fn capture_into(
        &mut self,
        cloud: &mut PointCloud,
        timeout: Duration,
    ) -> Result<bool, Self::Error>;

    /// The device's condition for the health heartbeat (a driver that knows nothing more
    /// reports connected and normal).
    fn health(&self) -> LidarHealth {
        LidarHealth::default()
    }
}
