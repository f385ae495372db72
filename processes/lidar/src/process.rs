//! `harvest lidar`: LiDAR device -> `lidar/points`.
//!
//! A [`Source`] node on the runtime ([`run_on_wake`], [`Wake::Device`]): each tick blocks in
//! the device's integrating capture (the device paces it; a timeout only serves the heartbeat
//! and shutdown), which writes the integrated cloud straight into a loaned `lidar/points`
//! sample; the runtime sends it. Fusion with the camera runs in the consumer (see
//! [`harvest_lidar::fusion`]).
//!
//! Devices: the simulated Mid-70 (`--device sim`) or a real one over the Livox SDK 1 protocol
//! (`--device livox`, found by `--broadcast-code` or reached at `--lidar-ip`). The heartbeat
//! is [`LidarCapture`]'s: the device's condition, the lost packets, the last cloud's points.

use harvest_hw::AnyDeviceError;
use harvest_hw::lidar::livox::command::BroadcastCode;
use harvest_hw::lidar::livox::{DeviceTarget, LivoxConfig, LivoxLidar};
use harvest_hw::lidar::sim::SimLidar;
use harvest_hw::lidar::{Lidar, LidarSpec};
use harvest_ipc::catalogue::LIDAR_POINTS;
use harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY;
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD};
use harvest_lidar::capture::LidarCapture;
use harvest_lidar::integration_window::max_window_s;
use harvest_node::Source;
use harvest_runtime::{RunError, Wake, WakeOptions, run_on_wake};
use std::net::Ipv4Addr;
use std::time::Duration;

/// Captures failing in a row after which the process stops (and is restarted).
pub const MAX_FAILURES_IN_A_ROW: u32 = 10;

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
    /// The run ended on an error (transport, too many failed captures in a row).
    #[error(transparent)]
    Run(#[from] RunError),
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

/// Streams `lidar`'s clouds on `lidar/points` until SIGINT/SIGTERM or an error.
fn stream<L: Lidar>(
    context: &Context,
    lidar: L,
    args: &LidarArgs,
) -> Result<(), LidarProcessError> {
    let source = Source::new(
        "lidar",
        LIDAR_POINTS,
        LidarCapture::new(lidar),
        HEARTBEAT_PERIOD / 2,
        MAX_FAILURES_IN_A_ROW,
    );
    let options = WakeOptions::sensor(Wake::Device, MAX_FAILURES_IN_A_ROW);
    tracing::info!(integration_s = args.integration_s, device = ?args.device, "lidar streaming");
    let finished = run_on_wake(context, source, (), options)?;
    let sent = finished.runner.node().counts().sent;
    finished.result?;
    tracing::info!(clouds = sent, "lidar stopped");
    Ok(())
}
