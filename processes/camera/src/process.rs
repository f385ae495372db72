//! `harvest camera`: device -> `camera/rgbd`.
//!
//! The loop blocks in the device's capture call (the device paces it; a timeout only serves the
//! heartbeat and shutdown), writes each frame straight into a loaned sample and sends it.
//!
//! Devices: the simulated ToF camera (`--device sim`) or a GigE Vision colour camera through
//! Aravis (`--device gige --config FILE [--camera-id ID]`; frames colour only, depth from the
//! LiDAR). The heartbeat's detail is the first of the link's losses that is not zero (lost
//! frames, missing packets, resent packets), else the device errors in a row.

use harvest_hw::rgbd_camera::gige::{GigeCamera, GigeConfig};
use harvest_hw::rgbd_camera::sim::SimRgbdCamera;
use harvest_hw::rgbd_camera::{CameraHealth, RgbdCamera};
use harvest_hw::{AnyDeviceError, DeviceError};
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::config_file::read_toml;
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD, HealthReporter};
use std::path::PathBuf;
use std::time::Instant;

/// Which camera device to drive (the one place the implementation is chosen).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CameraDevice {
    /// The simulated TL460 behind the `hw/camera/rgbd` hardware channel.
    Sim,
    /// A GigE Vision colour camera through Aravis (libaravis-0.8, loaded at run time).
    Gige,
}

#[derive(Debug, Clone, clap::Args)]
pub struct CameraArgs {
    #[arg(long, value_enum, default_value = "sim")]
    pub device: CameraDevice,
    /// Nominal frame rate of the device, for the status display (the device paces frames).
    #[arg(long, default_value_t = 30.0)]
    pub rate_hz: f64,
    /// GigE camera settings (TOML: pixel format, frame rate, exposure, packet size, the lens's
    /// intrinsics; see processes/camera/config/gige_fake.toml), required with `--device gige`.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The GigE camera to open (Aravis device id, serial number or IP address); overrides the
    /// config's `camera_id`.
    #[arg(long)]
    pub camera_id: Option<String>,
}

#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// The camera driver failed (opening it, or too many captures in a row); the source keeps the
    /// driver's error kind.
    #[error("camera device: {0}")]
    Device(#[source] AnyDeviceError),
    #[error("installing signal handler: {0}")]
    Signal(#[from] std::io::Error),
    /// The `--config` file cannot be used, or is missing.
    #[error("{0}")]
    Config(String),
}

harvest_ipc::from_ipc_errors!(CameraError);

/// Runs the camera process until SIGINT/SIGTERM.
pub fn run(args: &CameraArgs, domain: &Domain, process_name: &str) -> Result<(), CameraError> {
    harvest_ipc::termination::install_handler()?;
    let context = Context::new(domain, process_name)?;
    match args.device {
        CameraDevice::Sim => {
            let camera = SimRgbdCamera::connect(&context)
                .map_err(|error| CameraError::Device(AnyDeviceError::new(error)))?;
            stream(&context, camera, args)
        }
        CameraDevice::Gige => {
            let path = args.config.as_deref().ok_or_else(|| {
                CameraError::Config(
                    "--device gige needs --config FILE (the camera's settings and intrinsics)"
                        .to_owned(),
                )
            })?;
            let config: GigeConfig = read_toml(path, "GigE camera config")
                .map_err(|error| CameraError::Config(error.to_string()))?;
            if let Some(problem) = config.problem() {
                return Err(CameraError::Config(format!("{}: {problem}", path.display())));
            }
            let camera = GigeCamera::open(&config, args.camera_id.as_deref())
                .map_err(|error| CameraError::Device(AnyDeviceError::new(error)))?;
            stream(&context, camera, args)
        }
    }
}

/// The heartbeat's detail: the first non-zero loss of the link, else the errors in a row.
fn health_detail(link: &CameraHealth, consecutive_errors: u32) -> (&'static str, u64) {
    [
        ("lost_frames", link.lost_frames),
        ("missing_packets", link.missing_packets),
        ("resent_packets", link.resent_packets),
    ]
    .into_iter()
    .find(|&(_, count)| count > 0)
    .unwrap_or(("device_errors", u64::from(consecutive_errors)))
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
                let kind = error.kind();
                tracing::warn!(%error, %kind, "capture failed");
                health.note_device_error(kind.into());
                if consecutive_errors > 10 {
                    return Err(CameraError::Device(AnyDeviceError::new(error)));
                }
                loan = Some(frame);
            }
        }
        if Instant::now() >= next_heartbeat {
            next_heartbeat += HEARTBEAT_PERIOD;
            let state = if consecutive_errors > 0 {
                ProcessRunState::Degraded
            } else if frames.last_seq() == 0 {
                ProcessRunState::Starting
            } else {
                ProcessRunState::Running
            };
            let (detail, value) = health_detail(&camera.health(), consecutive_errors);
            health.report(state, frames.last_seq(), detail, value)?;
        }
    }
    tracing::info!(frames = frames.last_seq(), link = ?camera.health(), "camera stopped");
    Ok(())
}
