//! [`LidarCapture`]: a LiDAR driver as the device of the runtime's [`Source`] node
//! (`harvest lidar`), with what its heartbeat says.
//!
//! The heartbeat says `Degraded` while the device is lost (detail `disconnected`) or reports a
//! warning or error (detail: the condition), with the lost packets as the value, and for one
//! heartbeat after a capture error the driver already recovered from; otherwise `Running`
//! with the last cloud's points, or the lost packets once there are any.
//!
//! [`Source`]: harvest_node::Source

use std::time::Duration;

use harvest_hw::ErrorKind;
use harvest_hw::lidar::{Lidar, LidarCondition};
use harvest_ipc::payloads::{PointCloud, ProcessRunState};
use harvest_node::{Capture, SourceCounts};

/// A [`Lidar`] that integrates into loaned clouds and reports its condition.
#[derive(Debug)]
pub struct LidarCapture<L> {
    lidar: L,
    last_points: u64,
}

impl<L> LidarCapture<L> {
    pub fn new(lidar: L) -> Self {
        Self {
            lidar,
            last_points: 0,
        }
    }
}

/// The heartbeat's word for a capture error of this kind.
fn error_detail(kind: ErrorKind) -> &'static str {
    match kind {
        ErrorKind::Disconnected => "disconnected",
        ErrorKind::Timeout => "timeout",
        ErrorKind::Fault => "device_fault",
        ErrorKind::Protocol => "protocol_error",
        ErrorKind::InvalidRequest | ErrorKind::Other => "device_error",
    }
}

impl<L: Lidar> Capture<PointCloud> for LidarCapture<L> {
    type Error = L::Error;

    fn capture_into(
        &mut self,
        cloud: &mut PointCloud,
        timeout: Duration,
    ) -> Result<bool, L::Error> {
        let captured = self.lidar.capture_into(cloud, timeout)?;
        if captured {
            self.last_points = u64::from(cloud.meta.point_count);
            if cloud.meta.point_count == 0 {
                tracing::warn!("integrated cloud is empty (nothing in range?)");
            }
        }
        Ok(captured)
    }

    fn health(&self, counts: &SourceCounts) -> (ProcessRunState, &'static str, u64) {
        let health = self.lidar.health();
        let lost = health.lost_packets;
        let error = counts.error_since_heartbeat.map(error_detail);
        let (trouble, detail) = match (health.connected, health.condition, error) {
            (false, _, _) => (true, "disconnected"),
            (true, LidarCondition::Warning(what) | LidarCondition::Error(what), _) => (true, what),
            (true, LidarCondition::Normal, Some(what)) => (true, what),
            (true, LidarCondition::Normal, None) => (false, ""),
        };
        if counts.sent == 0 {
            let detail = if trouble { detail } else { "points" };
            return (ProcessRunState::Starting, detail, lost);
        }
        if trouble {
            return (ProcessRunState::Degraded, detail, lost);
        }
        if lost > 0 {
            (ProcessRunState::Running, "lost_packets", lost)
        } else {
            (ProcessRunState::Running, "points", self.last_points)
        }
    }
}
