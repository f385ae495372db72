//! `harvest camera`: device -> `camera/rgbd`.
//!
//! The loop blocks in the device's capture call (the device paces it; a timeout only serves the
//! heartbeat and shutdown), writes each frame straight into a loaned sample and sends it.

use harvest_hw::rgbd_camera::RgbdCamera;
use harvest_hw::rgbd_camera::sim::SimRgbdCamera;
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD, HealthReporter};
use std::time::Instant;

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
    #[error("camera device: {0}")]
    Device(String),
    #[error("installing signal handler: {0}")]
    Signal(#[from] std::io::Error),
}

harvest_ipc::from_ipc_errors!(CameraError);

/// Runs the camera process until SIGINT/SIGTERM.
pub fn run(args: &CameraArgs, domain: &Domain, process_name: &str) -> Result<(), CameraError> {
    harvest_ipc::termination::install_handler()?;
    let context = Context::new(domain, process_name)?;
    let camera = match args.device {
        CameraDevice::Sim => SimRgbdCamera::connect(&context)
            .map_err(|error| CameraError::Device(error.to_string()))?,
    };
    stream(&context, camera, args)
}

fn stream<C: RgbdCamera>(
    context: &Context,
    mut camera: C,
    args: &CameraArgs,
) -> Result<(), CameraError> {
    let mut frames = context.publisher(CAMERA_RGBD)?;
    let mut health = HealthReporter::new(context)?;
    let timeout = HEARTBEAT_PERIOD / 2;
    let mut next_heartbeat = Instant::now();
    let mut loan = None;
    let mut consecutive_errors = 0u32;
    tracing::info!(rate_hz = args.rate_hz, device = ?args.device, "camera streaming");
    while !harvest_ipc::termination::requested() {
        let mut frame = match loan.take() {
            Some(frame) => frame,
            None => frames.loan()?,
        };
        match camera.capture_into(&mut frame, timeout) {
            Ok(true) => {
                consecutive_errors = 0;
                let msg_seq = frames.send(frame)?;
                tracing::trace!(msg_seq, "frame published");
            }
            Ok(false) => loan = Some(frame),
            Err(error) => {
                consecutive_errors += 1;
                tracing::warn!(%error, kind = ?harvest_hw::DeviceError::kind(&error), "capture failed");
                if consecutive_errors > 10 {
                    return Err(CameraError::Device(error.to_string()));
                }
                loan = Some(frame);
            }
        }
        if Instant::now() >= next_heartbeat {
            next_heartbeat += HEARTBEAT_PERIOD;
            let state = if frames.last_seq() == 0 {
                ProcessRunState::Starting
            } else {
                ProcessRunState::Running
            };
            health.report(
                state,
                frames.last_seq(),
                "device_errors",
                u64::from(consecutive_errors),
            )?;
        }
    }
    tracing::info!(frames = frames.last_seq(), "camera stopped");
    Ok(())
}
