//! `harvest lidar`: LiDAR device -> `lidar/points`.
//!
//! The loop blocks in the device's integrating capture (the device paces it; a timeout only
//! serves the heartbeat and shutdown), writes each integrated cloud straight into a loaned
//! sample and sends it. Fusion with the camera runs in the consumer (see [`harvest_lidar::fusion`]).
//!
//! Devices: the simulated Mid-70 (`--device sim`) or a real one over the Livox SDK 1 protocol
//! (`--device livox`, found by `--broadcast-code` or reached at `--lidar-ip`). The health
//! heartbeat says `Degraded` while the device is lost (detail `disconnected`) or reports a
//! warning or error (detail: the condition), with the lost packets as the value, and for one
//! heartbeat after a capture error the driver already recovered from; otherwise
//! `Running` with the last cloud's points, or the lost packets once there are any.

use harvest_hw::lidar::livox::command::BroadcastCode;
use harvest_hw::lidar::livox::{DeviceTarget, LivoxConfig, LivoxLidar};
use harvest_hw::lidar::sim::SimLidar;
use harvest_hw::lidar::{Lidar, LidarCondition, LidarSpec};
use harvest_hw::{AnyDeviceError, DeviceError, ErrorKind};
use harvest_ipc::catalogue::LIDAR_POINTS;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY;
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD, HealthReporter};
use harvest_lidar::integration_window::max_window_s;
use std::net::Ipv4Addr;
use std::time::{Duration, Instant};

/// Which LiDAR device to drive (the one place the implementation is chosen).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LidarDevice {
    /// The simulated Mid-70 behind the `hw/lidar/points` hardware channel (`harvest sim --lidar`).
    Sim,
    /// A Livox Mid-70 over UDP (Livox SDK 1 protocol): `--broadcast-code` or `--lidar-ip`.
    Livox,
}

#[derive(Debug, Clone, clap::Args)]
pub struct LidarArgs {
    #[arg(long, value_enum, default_value = "sim")]
    pub device: LidarDevice,
    /// Integration window of one published cloud, seconds (the scan densifies with it; one
    /// cloud holds at most 1 s of the Mid-70's returns).
    #[arg(long, default_value_t = 1.0)]
    pub integration_s: f64,
    #[command(flatten)]
    pub livox: LivoxArgs,
}

/// How to reach a Livox device (`--device livox`).
#[derive(Debug, Clone, clap::Args)]
pub struct LivoxArgs {
    /// Find the device by its broadcast code (serial number, on its label) from its discovery
    /// broadcasts on `--discovery-port`.
    #[arg(long, conflicts_with = "lidar_ip")]
    pub broadcast_code: Option<String>,
    /// Handshake with the device at this address directly (no broadcast needed).
    #[arg(long)]
    pub lidar_ip: Option<Ipv4Addr>,
    /// The host address the device sends its points to (and the sockets bind to); default:
    /// the address the kernel routes towards the device, sockets on all interfaces.
    #[arg(long)]
    pub host_ip: Option<Ipv4Addr>,
    /// The device's command port.
    #[arg(long, default_value_t = harvest_hw::lidar::livox::command::DEVICE_CMD_PORT)]
    pub lidar_cmd_port: u16,
    /// Port the device's discovery broadcasts arrive on.
    #[arg(long, default_value_t = harvest_hw::lidar::livox::command::DISCOVERY_PORT)]
    pub discovery_port: u16,
    /// Host command port (0: any free port).
    #[arg(long, default_value_t = harvest_hw::lidar::livox::command::HOST_CMD_PORT)]
    pub host_cmd_port: u16,
    /// Host point-data port (0: any free port).
    #[arg(long, default_value_t = harvest_hw::lidar::livox::command::HOST_DATA_PORT)]
    pub host_data_port: u16,
    /// Silence after which the device is reported lost and reconnected, seconds.
    #[arg(long, default_value_t = 2.0)]
    pub silence_timeout_s: f64,
}

impl LivoxArgs {
    /// The driver configuration, or the option that is wrong.
    pub fn config(&self, integration: Duration) -> Result<LivoxConfig, LidarProcessError> {
        let target = match (&self.broadcast_code, self.lidar_ip) {
            (Some(code), None) => DeviceTarget::Broadcast(
                BroadcastCode::parse(code)
                    .map_err(|error| LidarProcessError::Config(error.to_string()))?,
            ),
            (None, Some(ip)) => DeviceTarget::Address(ip),
            _ => {
                return Err(LidarProcessError::Config(
                    "--device livox needs --broadcast-code CODE or --lidar-ip IP".to_string(),
                ));
            }
        };
        if !(self.silence_timeout_s >= 0.1 && self.silence_timeout_s <= 60.0) {
            return Err(LidarProcessError::Config(format!(
                "--silence-timeout-s {} outside 0.1..=60",
                self.silence_timeout_s
            )));
        }
        Ok(LivoxConfig {
            target,
            host_ip: self.host_ip,
            device_cmd_port: self.lidar_cmd_port,
            discovery_port: self.discovery_port,
            host_cmd_port: self.host_cmd_port,
            host_data_port: self.host_data_port,
            integration,
            silence_timeout: Duration::from_secs_f64(self.silence_timeout_s),
        })
    }
}

/// Errors of the LiDAR process.
#[derive(Debug, thiserror::Error)]
pub enum LidarProcessError {
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// The device failed (repeatedly) or could not be opened.
    #[error("lidar device: {0}")]
    Device(#[source] AnyDeviceError),
    /// A device option is missing or wrong (the message names it).
    #[error("lidar options: {0}")]
    Config(String),
    /// `--integration-s` is outside what one cloud can hold.
    #[error(
        "--integration-s {integration_s} outside 0.1..={max_s} s (one cloud holds {capacity} points)"
    )]
    BadIntegration {
        integration_s: f64,
        max_s: f64,
        capacity: usize,
    },
    #[error("installing signal handler: {0}")]
    Signal(#[from] std::io::Error),
}

harvest_ipc::from_ipc_errors!(LidarProcessError);

/// Runs the LiDAR process until SIGINT/SIGTERM.
pub fn run(args: &LidarArgs, domain: &Domain, process_name: &str) -> Result<(), LidarProcessError> {
    let max_s = max_window_s(&LidarSpec::mid70());
    if !(args.integration_s >= 0.1 && args.integration_s <= max_s) {
        return Err(LidarProcessError::BadIntegration {
            integration_s: args.integration_s,
            max_s,
            capacity: POINT_CLOUD_CAPACITY,
        });
    }
    harvest_ipc::termination::install_handler()?;
    let context = Context::new(domain, process_name)?;
    let integration = Duration::from_secs_f64(args.integration_s);
    match args.device {
        LidarDevice::Sim => {
            let lidar = SimLidar::connect(&context, integration)
                .map_err(|error| LidarProcessError::Device(AnyDeviceError::new(error)))?;
            stream(&context, lidar, args)
        }
        LidarDevice::Livox => {
            let lidar = LivoxLidar::open(args.livox.config(integration)?)
                .map_err(|error| LidarProcessError::Device(AnyDeviceError::new(error)))?;
            stream(&context, lidar, args)
        }
    }
}

/// The heartbeat's state, detail and value from the device's health (see the module docs).
/// `error_since_last`: the detail of a capture error since the previous heartbeat, so a loss
/// the driver recovered from between two heartbeats is still reported once.
fn health_report<L: Lidar>(
    lidar: &L,
    clouds_sent: u64,
    last_points: u64,
    error_since_last: Option<&'static str>,
) -> (ProcessRunState, &'static str, u64) {
    let health = lidar.health();
    let lost = health.lost_packets;
    let (trouble, detail) = match (health.connected, health.condition, error_since_last) {
        (false, _, _) => (true, "disconnected"),
        (true, LidarCondition::Warning(what) | LidarCondition::Error(what), _) => (true, what),
        (true, LidarCondition::Normal, Some(what)) => (true, what),
        (true, LidarCondition::Normal, None) => (false, ""),
    };
    if clouds_sent == 0 {
        let detail = if trouble { detail } else { "points" };
        return (ProcessRunState::Starting, detail, lost);
    }
    if trouble {
        return (ProcessRunState::Degraded, detail, lost);
    }
    if lost > 0 {
        (ProcessRunState::Running, "lost_packets", lost)
    } else {
        (ProcessRunState::Running, "points", last_points)
    }
}

fn stream<L: Lidar>(
    context: &Context,
    mut lidar: L,
    args: &LidarArgs,
) -> Result<(), LidarProcessError> {
    let mut clouds = context.publisher(LIDAR_POINTS)?;
    let mut health = HealthReporter::new(context)?;
    let timeout = HEARTBEAT_PERIOD / 2;
    let mut next_heartbeat = Instant::now();
    let mut loan = None;
    let mut consecutive_errors = 0u32;
    let mut last_points = 0u64;
    let mut error_since_heartbeat: Option<&'static str> = None;
    tracing::info!(integration_s = args.integration_s, device = ?args.device, "lidar streaming");
    while !harvest_ipc::termination::requested() {
        let mut cloud = match loan.take() {
            Some(cloud) => cloud,
            None => clouds.loan()?,
        };
        match lidar.capture_into(&mut cloud, timeout) {
            Ok(true) => {
                consecutive_errors = 0;
                last_points = u64::from(cloud.meta.point_count);
                if cloud.meta.point_count == 0 {
                    tracing::warn!("integrated cloud is empty (nothing in range?)");
                }
                let msg_seq = clouds.send(cloud)?;
                tracing::trace!(msg_seq, points = last_points, "cloud published");
            }
            Ok(false) => loan = Some(cloud),
            Err(error) => {
                consecutive_errors += 1;
                error_since_heartbeat = Some(match error.kind() {
                    ErrorKind::Disconnected => "disconnected",
                    ErrorKind::Timeout => "timeout",
                    ErrorKind::Fault => "device_fault",
                    ErrorKind::Protocol => "protocol_error",
                    ErrorKind::InvalidRequest | ErrorKind::Other => "device_error",
                });
                tracing::warn!(%error, kind = %error.kind(), "capture failed");
                health.note_device_error(error.kind().into());
                if consecutive_errors > 10 {
                    return Err(LidarProcessError::Device(AnyDeviceError::new(error)));
                }
                loan = Some(cloud);
            }
        }
        if Instant::now() >= next_heartbeat {
            next_heartbeat += HEARTBEAT_PERIOD;
            let (state, detail, value) = health_report(
                &lidar,
                clouds.last_seq(),
                last_points,
                error_since_heartbeat.take(),
            );
            health.report(state, clouds.last_seq(), detail, value)?;
        }
    }
    tracing::info!(clouds = clouds.last_seq(), "lidar stopped");
    Ok(())
}
