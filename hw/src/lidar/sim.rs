//! The simulated LiDAR as a device: the simulator ray-casts the scan pattern against its world
//! and streams short frames (10 Hz, like the Livox driver) on `hw/lidar/points`; this driver
//! integrates consecutive frames into one cloud per integration window, the way the Livox SDK's
//! point accumulation does on the host.
//!
//! The integration window is counted in device scan time: frames are added until the sum of
//! their scan durations (`meta.integration_ns` of each frame) reaches `integration`, so a 1 s
//! window holds exactly ten 100 ms frames whatever the delivery jitter. A dropped frame (a gap
//! in the device's sequence) is integrated across; the cloud's `meta.integration_ns` is the scan
//! time it holds.

use super::Lidar;
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::HW_LIDAR_POINTS;
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::PointCloud;
use harvest_ipc::{Context, Subscriber};
use std::time::{Duration, Instant};

/// Errors of the simulated LiDAR link.
#[derive(Debug, thiserror::Error)]
pub enum SimLidarError {
    /// The hardware channel could not be opened or read.
    #[error("simulated lidar link: {0}")]
    Link(#[from] IpcError),
    /// The requested integration window is not positive and finite.
    #[error("lidar integration time {integration_s} s is not positive and finite")]
    BadIntegration {
        /// The window asked for, seconds.
        integration_s: f64,
    },
}

impl DeviceError for SimLidarError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Link(_) => ErrorKind::Disconnected,
            Self::BadIntegration { .. } => ErrorKind::InvalidRequest,
        }
    }
}

/// Driver of the simulated LiDAR.
pub struct SimLidar {
    frames: Subscriber<PointCloud>,
    integration_ns: u64,
    /// The window being integrated (driver-owned, so a timeout loses nothing).
    window: Box<PointCloud>,
}

impl SimLidar {
    /// Connects to `hw/lidar/points` and integrates windows of `integration`.
    pub fn connect(context: &Context, integration: Duration) -> Result<Self, SimLidarError> {
        if integration.is_zero() {
            return Err(SimLidarError::BadIntegration { integration_s: 0.0 });
        }
        let frames = context
            .subscriber_with_buffer(HW_LIDAR_POINTS, 8)
            .map_err(|error| SimLidarError::Link(error.into()))?;
        let mut window: Box<PointCloud> = harvest_ipc::payload::boxed_zeroed();
        window.clear();
        Ok(Self {
            frames,
            integration_ns: integration.as_nanos() as u64,
            window,
        })
    }

    /// Takes every frame waiting on the channel into the window; true once the window is full.
    fn drain(&mut self) -> Result<bool, SimLidarError> {
        while let Some(frame) = self
            .frames
            .receive()
            .map_err(|error| SimLidarError::Link(error.into()))?
        {
            let before = self.window.meta.point_count;
            self.window.extend_from_slice(frame.valid_points());
            self.window.meta.flags |= frame.meta.flags;
            self.window.header.capture_ns = frame.header.capture_ns;
            self.window.meta.integration_ns += frame.meta.integration_ns;
            tracing::trace!(
                frame_points = self.window.meta.point_count - before,
                window_points = self.window.meta.point_count,
                "lidar frame integrated"
            );
            if self.window.meta.integration_ns + 1_000 >= self.integration_ns {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Moves the full window into `cloud` and starts the next one.
    fn deliver(&mut self, cloud: &mut PointCloud) {
        cloud.header.capture_ns = self.window.header.capture_ns;
        cloud.meta = self.window.meta;
        let count = self.window.valid_points().len();
        cloud.points[..count].copy_from_slice(&self.window.points[..count]);
        self.window.clear();
    }
}

impl Lidar for SimLidar {
    type Error = SimLidarError;

    fn capture_into(
        &mut self,
        cloud: &mut PointCloud,
        timeout: Duration,
    ) -> Result<bool, Self::Error> {
        let deadline = Instant::now() + timeout;
        loop {
            if self.drain()? {
                self.deliver(cloud);
                return Ok(true);
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(false);
            }
            // An interrupted wait (a signal arrived) is a timeout: the caller checks for shutdown.
            if let Err(error) = self.frames.listener().timed_wait(|_| {}, deadline - now) {
                tracing::debug!(?error, "wait for lidar frame interrupted");
                return Ok(false);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::lost_link;

    #[test]
    fn every_error_maps_to_its_kind() {
        let refused = SimLidarError::BadIntegration { integration_s: 0.0 };
        assert_eq!(refused.kind(), ErrorKind::InvalidRequest);
        assert_eq!(
            SimLidarError::from(lost_link()).kind(),
            ErrorKind::Disconnected
        );
    }
}
