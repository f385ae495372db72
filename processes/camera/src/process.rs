//! `harvest camera`: camera device -> `camera/rgbd`.
//!
//! The camera is a [`Source`] node on the runtime ([`run_on_wake`], [`Wake::Device`]): the
//! device paces it; each tick's capture blocks in the driver (event-driven; a timeout only
//! serves the heartbeat and shutdown) and writes the frame straight into a loaned
//! `camera/rgbd` sample, which the runtime sends. More than [`MAX_FAILURES_IN_A_ROW`] failed
//! captures in a row end the process (the supervisor restarts it); each is reported by kind.

use std::time::Duration;

use harvest_hw::AnyDeviceError;
use harvest_hw::rgbd_camera::sim::SimRgbdCamera;
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD};
use harvest_node::{Capture, RunnerConfig, Source};
use harvest_robot_model::ModeSource;
use harvest_runtime::{RunError, Wake, WakeOptions, run_on_wake};

/// Captures failing in a row after which the process stops (and is restarted).
pub const MAX_FAILURES_IN_A_ROW: u32 = 10;

/// Which camera device to drive (the one place the implementation is chosen).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CameraDevice {
    /// The simulated TL460 behind the `hw/camera/rgbd` hardware channel.
    Sim,
}

#[derive(Debug, Clone, clap::Args)]
pub struct CameraArgs {
    #[arg(long, value_enum, default_value = "sim")]
    pub device: CameraDevice,
    /// Nominal frame rate of the device, for the status display (the device paces frames).
    #[arg(long, default_value_t = 30.0)]
    pub rate_hz: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// The camera driver could not be opened; the source keeps the driver's error kind.
    #[error("camera device: {0}")]
    Device(#[source] AnyDeviceError),
    /// The run ended on an error (transport, too many failed captures in a row).
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(CameraError);

/// Runs the camera process until SIGINT/SIGTERM.
pub fn run(args: &CameraArgs, domain: &Domain, process_name: &str) -> Result<(), CameraError> {
    let context = Context::new(domain, process_name)?;
    let camera = match args.device {
        CameraDevice::Sim => SimRgbdCamera::connect(&context)
            .map_err(|error| CameraError::Device(AnyDeviceError::new(error)))?,
    };
    stream(&context, camera, args)
}

/// Streams `camera` on `camera/rgbd` until SIGINT/SIGTERM or an error.
pub fn stream<C: Capture<harvest_ipc::payloads::RgbdFrame>>(
    context: &Context,
    camera: C,
    args: &CameraArgs,
) -> Result<(), CameraError> {
    let timeout: Duration = HEARTBEAT_PERIOD / 2;
    let source = Source::new(
        "camera",
        CAMERA_RGBD,
        camera,
        timeout,
        MAX_FAILURES_IN_A_ROW,
    );
    let options = WakeOptions {
        wake: Wake::Device,
        runner: RunnerConfig {
            max_read_failures: MAX_FAILURES_IN_A_ROW,
            mode_source: ModeSource::WithoutOperator,
        },
        obeys: false,
        stop: None,
    };
    tracing::info!(rate_hz = args.rate_hz, device = ?args.device, "camera streaming");
    let finished = run_on_wake(context, source, (), options)?;
    let sent = finished.runner.node().counts().sent;
    finished.result?;
    tracing::info!(frames = sent, "camera stopped");
    Ok(())
}
