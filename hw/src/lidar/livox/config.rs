//! How to reach the device and how to integrate its points.

use super::command::{
    BroadcastCode, DEVICE_CMD_PORT, DISCOVERY_PORT, HOST_CMD_PORT, HOST_DATA_PORT,
};
use std::net::Ipv4Addr;
use std::time::Duration;

/// Which device to talk to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceTarget {
    /// Wait for this device's discovery broadcast and use the address it came from.
    Broadcast(BroadcastCode),
    /// Handshake with the device at this address directly.
    Address(Ipv4Addr),
}

/// Silence after which the device counts as lost: with the heartbeat once a second, the loss is
/// known within 2 s and the process's health (every 0.5 s) reports it within 3 s.
pub const DEFAULT_SILENCE_TIMEOUT: Duration = Duration::from_secs(2);

/// Driver configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LivoxConfig {
    /// Which device to talk to (broadcast code or address).
    pub target: DeviceTarget,
    /// The host address handed to the device (where it sends data) and the one the sockets bind
    /// to; None: the address the kernel routes towards the device, sockets on all interfaces.
    pub host_ip: Option<Ipv4Addr>,
    /// The device's command port (65000 on every Livox SDK 1 device).
    pub device_cmd_port: u16,
    /// Port of the discovery broadcasts (55000).
    pub discovery_port: u16,
    /// Host command port (the SDK's 55501); 0 picks a free one.
    pub host_cmd_port: u16,
    /// Host data port (the SDK's 56001); 0 picks a free one.
    pub host_data_port: u16,
    /// Integration window of one cloud, device time.
    pub integration: Duration,
    /// Silence after which the device is reported lost and reconnected.
    pub silence_timeout: Duration,
}

impl LivoxConfig {
    /// The SDK's ports, a 1 s window and the default silence timeout.
    pub fn new(target: DeviceTarget) -> Self {
        Self {
            target,
            host_ip: None,
            device_cmd_port: DEVICE_CMD_PORT,
            discovery_port: DISCOVERY_PORT,
            host_cmd_port: HOST_CMD_PORT,
            host_data_port: HOST_DATA_PORT,
            integration: Duration::from_secs(1),
            silence_timeout: DEFAULT_SILENCE_TIMEOUT,
        }
    }
}
