//! `harvest lidar`: LiDAR device -> `lidar/points`.
//!
//! The loop blocks in the device's integrating capture (the device paces it; a timeout only
//! serves the heartbeat and shutdown), writes each integrated cloud straight into a loaned
//! sample and sends it. Fusion with the camera runs in the consumer (see [`harvest_lidar::fusion`]).

use harvest_hw::lidar::Lidar;
use harvest_hw::lidar::LidarSpec;
use harvest_hw::lidar::sim::SimLidar;
use harvest_hw::{AnyDeviceError, DeviceError};
use harvest_ipc::catalogue::LIDAR_POINTS;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY;
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD, HealthReporter};
use harvest_lidar::integration_window::max_window_s;
use std::time::{Duration, Instant};

/// Which LiDAR device to drive (the one place the implementation is chosen).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LidarDevice {
    /// The simulated Mid-70 behind the `hw/lidar/points` hardware channel (`harvest sim --lidar`).
    Sim,
}

#[derive(Debug, Clone, clap::Args)]
pub struct LidarArgs {
    #[arg(long, value_enum, default_value = "sim")]
    pub device: LidarDevice,
    /// Integration window of one published cloud, seconds (the scan densifies with it; one
    /// cloud holds at most 1 s of the Mid-70's returns).
    #[arg(long, default_value_t = 1.0)]
    pub integration_s: f64,
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
    let lidar = match args.device {
        LidarDevice::Sim => SimLidar::connect(&context, integration)
            .map_err(|error| LidarProcessError::Device(AnyDeviceError::new(error)))?,
    };
    stream(&context, lidar, args)
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
                let kind = error.kind();
                tracing::warn!(%error, %kind, "capture failed");
                health.note_device_error(kind.into());
                if consecutive_errors > 10 {
                    return Err(LidarProcessError::Device(AnyDeviceError::new(error)));
                }
                loan = Some(cloud);
            }
        }
        if Instant::now() >= next_heartbeat {
            next_heartbeat += HEARTBEAT_PERIOD;
            let state = if consecutive_errors > 0 {
                ProcessRunState::Degraded
            } else if clouds.last_seq() == 0 {
                ProcessRunState::Starting
            } else {
                ProcessRunState::Running
            };
            health.report(state, clouds.last_seq(), "points", last_points)?;
        }
    }
    tracing::info!(clouds = clouds.last_seq(), "lidar stopped");
    Ok(())
}
