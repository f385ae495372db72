//! What a LiDAR driver tells its process about the device, beyond the clouds: for the health
//! heartbeat and the operator.

/// The device's own report of its condition.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum LidarCondition {
    #[default]
    /// Measuring normally.
    Normal,
    /// Still measuring, but something needs attention (the name says what).
    Warning(&'static str),
    /// The device reports it cannot measure properly.
    Error(&'static str),
}

/// A driver's view of its device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LidarHealth {
    /// Returns are flowing (false while the device is lost and being reconnected).
    pub connected: bool,
    /// The device's own report of its condition.
    pub condition: LidarCondition,
    /// Packets the device sent that never arrived, since start.
    pub lost_packets: u64,
    /// Datagrams dropped as malformed, since start.
    pub bad_packets: u64,
}

impl Default for LidarHealth {
    fn default() -> Self {
        Self {
            connected: true,
            condition: LidarCondition::Normal,
            lost_packets: 0,
            bad_packets: 0,
        }
    }
}
