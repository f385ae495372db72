//! The Mid-70 behind the [`Lidar`] trait: the session's point packets decoded straight into
//! the caller's cloud (the loaned `lidar/points` sample), one integration window per cloud.
//!
//! Windows are cut in device time: a window `[start, start + integration)` takes every firing
//! stamped inside it, so a packet straddling the boundary is split (its later firings, at most
//! 95, wait in a small carry buffer for the next cloud) and consecutive clouds tile the scan
//! without overlap. `meta.integration_ns` is the scan time the cloud holds (firings received x
//! 10 us: lost packets leave it short), `header.capture_ns` the end of the window mapped to the
//! stack's clock ([`ClockMapping`]), no later than the newest packet's arrival. Firings without
//! a return (reported at the origin) are not written. A dual-return packet gives two returns
//! per firing: a one-second window would hold 200,000, twice a cloud's capacity, so dual-return
//! windows of more than 0.5 s come truncated (`PointCloudMeta::FLAG_TRUNCATED`).
//!
//! Lost packets: the firings are 10 us apart, so each packet's first firing should follow the
//! previous packet's last by 10 us; a later start counts the packets that fit in the gap. A
//! start earlier than expected by more than half a packet is a device time restart (reboot,
//! time step): the partial window is dropped and the clock mapping starts over. A window never
//! spans a loss of the device: the partial window is dropped when the session reports silence,
//! and the gap to the first packet after the reconnection is not counted as lost packets.
//!
//! Bad datagrams on the data port (truncated, wrong length, version, data or timestamp type)
//! are counted by reason and dropped, as are datagrams from any address but the device's.

use super::clock_mapping::ClockMapping;
use super::config::LivoxConfig;
use super::error::LivoxError;
use super::error_code::Severity;
use super::point_packet::{self, FIRING_PERIOD_NS, PacketError};
use super::session::{self, Session, SessionCounters, SessionEvent, SessionState};
use crate::lidar::{Lidar, LidarCondition, LidarHealth};
use harvest_ipc::MonotonicClock;
use harvest_ipc::payloads::{LidarPoint, PointCloud};
use std::time::{Duration, Instant};

/// Datagrams dropped from the data port, by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BadPacketCounts {
    /// Shorter than their header.
    pub truncated: u64,
    /// Longer or shorter than their data type holds.
    pub bad_length: u64,
    /// With a protocol version other than 5.
    pub bad_version: u64,
    /// With a data type the driver does not decode.
    pub unknown_data_type: u64,
    /// With a timestamp type the driver does not know.
    pub unknown_timestamp_type: u64,
    /// With a timestamp that does not map onto the stack clock.
    pub bad_timestamp: u64,
    /// From an address other than the device's.
    pub foreign: u64,
}

impl BadPacketCounts {
    /// Datagrams dropped, whatever the reason.
    pub fn total(&self) -> u64 {
        self.truncated
            + self.bad_length
            + self.bad_version
            + self.unknown_data_type
            + self.unknown_timestamp_type
            + self.bad_timestamp
            + self.foreign
    }

    fn count(&mut self, error: &PacketError) {
        let counter = match error {
            PacketError::Truncated { .. } => &mut self.truncated,
            PacketError::BadLength { .. } => &mut self.bad_length,
            PacketError::BadVersion { .. } => &mut self.bad_version,
            PacketError::UnknownDataType { .. } => &mut self.unknown_data_type,
            PacketError::UnknownTimestampType { .. } => &mut self.unknown_timestamp_type,
            PacketError::BadTimestamp => &mut self.bad_timestamp,
        };
        *counter += 1;
    }
}

/// What the driver has seen since it started.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LivoxStats {
    /// Valid point packets received.
    pub packets: u64,
    /// Packets missing from the device's stream (timestamp gaps).
    pub lost_packets: u64,
    /// Dropped datagrams of the data port.
    pub bad_packets: BadPacketCounts,
    /// Times the device's time ran backwards (a reboot or a time step).
    pub device_time_restarts: u64,
    /// Clouds delivered.
    pub clouds: u64,
    /// The control link's counters (bad frames, losses, reconnects).
    pub session: SessionCounters,
    /// Restarts of the clock mapping.
    pub clock_resets: u64,
}

/// The window being filled.
#[derive(Debug, Clone, Copy, Default)]
struct Window {
    /// A cloud has been started (cleared) for this window.
    open: bool,
    /// Device time of the window's start and end (None until the first firing).
    span_ns: Option<(u64, u64)>,
    /// Firings held.
    firings: u64,
    /// Device time just after the last firing held.
    held_until_ns: u64,
}

/// Driver of a Livox Mid-70 over its SDK 1 protocol.
pub struct LivoxLidar {
    session: Session,
    clock: ClockMapping,
    integration_ns: u64,
    window: Window,
    /// Returns of a straddling packet that belong to the next window, with their firing count
    /// and the device time of their first firing.
    carry: Vec<LidarPoint>,
    carry_firings: u64,
    carry_start_ns: Option<u64>,
    /// Device time the next packet's first firing should have.
    next_expected_ns: Option<u64>,
    stats: LivoxStats,
    datagram: Vec<u8>,
}

impl LivoxLidar {
    /// Opens the sockets; the device is found and handshaken inside [`Lidar::capture_into`].
    pub fn open(config: LivoxConfig) -> Result<Self, LivoxError> {
        let integration_ns = u64::try_from(config.integration.as_nanos()).unwrap_or(u64::MAX);
        if integration_ns < FIRING_PERIOD_NS {
            return Err(LivoxError::Config(format!(
                "integration window {:?} shorter than one firing",
                config.integration
            )));
        }
        if config.silence_timeout < Duration::from_millis(100) {
            return Err(LivoxError::Config(format!(
                "silence timeout {:?} under 100 ms",
                config.silence_timeout
            )));
        }
        Ok(Self {
            session: Session::open(config)?,
            clock: ClockMapping::new(),
            integration_ns,
            window: Window::default(),
            carry: Vec::with_capacity(point_packet::DataType::ExtendedCartesian.firings() * 2),
            carry_firings: 0,
            carry_start_ns: None,
            next_expected_ns: None,
            stats: LivoxStats::default(),
            datagram: vec![0; 2048],
        })
    }

    /// Counters since the driver opened (packets, points, losses, reconnections).
    pub fn stats(&self) -> LivoxStats {
        LivoxStats {
            session: self.session.counters(),
            clock_resets: self.clock.resets(),
            ..self.stats
        }
    }

    /// The control session with the device (state and counters).
    pub fn session(&self) -> &Session {
        &self.session
    }

    fn open_window(&mut self, cloud: &mut PointCloud) {
        cloud.clear();
        self.window = Window {
            open: true,
            ..Window::default()
        };
        if let Some(start) = self.carry_start_ns.take() {
            cloud.extend_from_slice(&self.carry);
            self.window.span_ns = Some((start, start.saturating_add(self.integration_ns)));
            self.window.firings = self.carry_firings;
            self.window.held_until_ns = start + self.carry_firings * FIRING_PERIOD_NS;
        }
        self.carry.clear();
        self.carry_firings = 0;
    }

    /// Drops the partial window and anything carried (the stream broke).
    fn drop_window(&mut self, cloud: &mut PointCloud) {
        self.carry.clear();
        self.carry_firings = 0;
        self.carry_start_ns = None;
        self.open_window(cloud);
    }

    /// Finishes the window into `cloud`.
    fn deliver(&mut self, cloud: &mut PointCloud) {
        let end_ns = match self.window.span_ns {
            Some((_, end)) => end.min(self.window.held_until_ns),
            None => self.window.held_until_ns,
        };
        // The window ends one firing period after its last firing, which the mapping (paired
        // with a packet's last firing) may put a few microseconds after that packet arrived:
        // a stamp is never later than the arrival of the newest data.
        cloud.header.capture_ns = self
            .clock
            .to_host_ns(end_ns)
            .map_or(0, |stamp| stamp.min(self.clock.last_host_ns()));
        cloud.meta.integration_ns = self.window.firings * FIRING_PERIOD_NS;
        self.window.open = false;
        self.stats.clouds += 1;
        tracing::trace!(
            points = cloud.meta.point_count,
            firings = self.window.firings,
            "livox window delivered"
        );
    }

    /// Takes one datagram of the data port; true when it completed the window.
    fn on_datagram(&mut self, len: usize, receive_ns: u64, cloud: &mut PointCloud) -> bool {
        let datagram = std::mem::take(&mut self.datagram);
        let complete = self.on_packet(&datagram[..len], receive_ns, cloud);
        self.datagram = datagram;
        complete
    }

    fn on_packet(&mut self, datagram: &[u8], receive_ns: u64, cloud: &mut PointCloud) -> bool {
        let packet = match point_packet::decode_point_packet(datagram) {
            Ok(packet) => packet,
            Err(error) => {
                self.stats.bad_packets.count(&error);
                tracing::debug!(%error, "point packet dropped");
                return false;
            }
        };
        let header = packet.header;
        let Ok(first_ns) = header.first_firing_ns() else {
            return false;
        };
        self.stats.packets += 1;
        self.session.packet_status(header.status_code);
        let data_type = header.data_type;
        let firings = data_type.firings() as u64;
        let span_ns = data_type.packet_span_ns();
        if let Some(expected) = self.next_expected_ns {
            if first_ns + span_ns / 2 < expected {
                self.stats.device_time_restarts += 1;
                tracing::warn!(first_ns, expected, "livox device time restarted");
                self.drop_window(cloud);
            } else if first_ns >= expected + span_ns / 2 {
                let lost = (first_ns - expected + span_ns / 2) / span_ns;
                self.stats.lost_packets += lost;
                tracing::debug!(lost, "livox point packets lost");
            }
        }
        self.next_expected_ns = Some(first_ns + span_ns);
        let last_firing_ns = first_ns + (firings - 1) * FIRING_PERIOD_NS;
        self.clock.observe(last_firing_ns, receive_ns);

        let (start, end) = *self
            .window
            .span_ns
            .get_or_insert((first_ns, first_ns.saturating_add(self.integration_ns)));
        let _ = start;
        // Firings of this packet inside the window.
        let inside = if first_ns >= end {
            0
        } else {
            (end - first_ns).div_ceil(FIRING_PERIOD_NS).min(firings)
        };
        let per_firing = data_type.returns_per_firing();
        let split = inside as usize * per_firing;
        for (index, raw) in packet.returns().enumerate() {
            if raw.is_empty() {
                continue;
            }
            let point = LidarPoint {
                x_m: raw.x_mm as f32 / 1000.0,
                y_m: raw.y_mm as f32 / 1000.0,
                z_m: raw.z_mm as f32 / 1000.0,
                intensity: f32::from(raw.reflectivity),
            };
            if index < split {
                cloud.push(point);
            } else {
                self.carry.push(point);
            }
        }
        if inside > 0 {
            self.window.firings += inside;
            self.window.held_until_ns = first_ns + inside * FIRING_PERIOD_NS;
        }
        if inside < firings {
            self.carry_firings = firings - inside;
            self.carry_start_ns = Some(first_ns + inside * FIRING_PERIOD_NS);
        }
        let complete = first_ns + firings * FIRING_PERIOD_NS >= end;
        if complete {
            self.deliver(cloud);
        }
        complete
    }
}

impl Lidar for LivoxLidar {
    type Error = LivoxError;

    fn capture_into(
        &mut self,
        cloud: &mut PointCloud,
        timeout: Duration,
    ) -> Result<bool, Self::Error> {
        let deadline = Instant::now() + timeout;
        if !self.window.open {
            self.open_window(cloud);
        }
        loop {
            let now = Instant::now();
            if let Some(SessionEvent::Lost { silent_for }) = self.session.service(now)? {
                self.drop_window(cloud);
                self.next_expected_ns = None;
                self.clock.clear();
                return Err(LivoxError::Silent {
                    device: self
                        .session
                        .device()
                        .map_or_else(|| "(not found)".to_string(), |d| d.to_string()),
                    silent_for,
                });
            }
            while let Some((len, from)) =
                session::recv(Some(self.session.data_socket()), &mut self.datagram)?
            {
                let receive_ns = MonotonicClock::read_ns();
                if !self.session.is_device(&from) {
                    self.stats.bad_packets.foreign += 1;
                    continue;
                }
                self.session.heard(Instant::now());
                if self.on_datagram(len, receive_ns, cloud) {
                    return Ok(true);
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(false);
            }
            let until = self.session.next_due(now).min(deadline);
            self.session.wait(now, until)?;
        }
    }

    fn health(&self) -> LidarHealth {
        let status = self.session.status();
        let condition = match (status.severity(), status.conditions().next()) {
            (Severity::Normal, _) => LidarCondition::Normal,
            (Severity::Warning, what) => LidarCondition::Warning(what.unwrap_or("device_warning")),
            (Severity::Error, what) => LidarCondition::Error(what.unwrap_or("device_error")),
        };
        let stats = self.stats();
        LidarHealth {
            connected: self.session.state() == SessionState::Streaming,
            condition,
            lost_packets: stats.lost_packets,
            bad_packets: stats.bad_packets.total() + stats.session.bad_frames,
        }
    }
}
