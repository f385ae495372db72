//! `harvest camera`: camera device -> `camera/rgbd`.
//!
//! The camera is a [`Source`] node on the runtime ([`run_on_wake`], [`Wake::Device`]): the
//! device paces it; each tick's capture blocks in the driver (event-driven; a timeout only
//! serves the heartbeat and shutdown) and writes the frame straight into a loaned
//! `camera/rgbd` sample, which the runtime sends. More than [`MAX_FAILURES_IN_A_ROW`] failed
//! captures in a row end the process (the supervisor restarts it); each is reported by kind.
//!
//! Devices: the simulated ToF camera (`--device sim`) or a GigE Vision colour camera through
//! Aravis (`--device gige --config FILE [--camera-id ID]`; its frames are colour only, the depth
//! comes from the LiDAR). The heartbeat's detail is the capture failures in a row while they
//! last, else the first of the link's losses that is not zero (lost frames, missing packets,
//! resent packets).

use std::path::{Path, PathBuf};
use std::time::Duration;

use harvest_hw::AnyDeviceError;
use harvest_hw::rgbd_camera::RgbdCamera;
use harvest_hw::rgbd_camera::gige::{GigeCamera, GigeConfig};
use harvest_hw::rgbd_camera::sim::SimRgbdCamera;
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::config_file::{ConfigFileError, read_toml};
use harvest_ipc::{Context, Domain, HEARTBEAT_PERIOD};
use harvest_node::Source;
use harvest_runtime::{RunError, Wake, WakeOptions, run_on_wake};

/// Captures failing in a row after which the process stops (and is restarted).
pub const MAX_FAILURES_IN_A_ROW: u32 = 10;

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
    /// intrinsics; `sim/gige_camera.toml` is an example), required with `--device gige`.
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
    /// The camera driver could not be opened; the source keeps the driver's error kind.
    #[error("camera device: {0}")]
    Device(#[source] AnyDeviceError),
    /// The `--config` file cannot be read or parsed (the error names the file, line and key).
    #[error(transparent)]
    ConfigFile(#[from] ConfigFileError),
    /// `--config` is missing, or the file's settings are unusable (named with the file, key and
    /// value).
    #[error("{0}")]
    Config(String),
    /// The run ended on an error (transport, too many failed captures in a row).
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(CameraError);

/// Runs the camera process until SIGINT/SIGTERM.
pub fn run(args: &CameraArgs, domain: &Domain, process_name: &str) -> Result<(), CameraError> {
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
            let camera = GigeCamera::open(&read_gige_config(path)?, args.camera_id.as_deref())
                .map_err(|error| CameraError::Device(AnyDeviceError::new(error)))?;
            stream(&context, camera, args)
        }
    }
}

/// The GigE camera's settings from `path`: TOML with unknown keys refused (the parser's error
/// names the file, line and key), then the values checked (the error names the file, key and
/// value).
pub fn read_gige_config(path: &Path) -> Result<GigeConfig, CameraError> {
    let config: GigeConfig = read_toml(path, "GigE camera config")?;
    match config.problem() {
        Some(problem) => Err(CameraError::Config(format!(
            "GigE camera config {}: {problem}",
            path.display()
        ))),
        None => Ok(config),
    }
}

/// Streams `camera` on `camera/rgbd` until SIGINT/SIGTERM or an error.
pub fn stream<C: RgbdCamera>(
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
    let options = WakeOptions::sensor(Wake::Device, MAX_FAILURES_IN_A_ROW);
    tracing::info!(rate_hz = args.rate_hz, device = ?args.device, "camera streaming");
    let finished = run_on_wake(context, source, (), options)?;
    let source = finished.runner.node();
    let (sent, link) = (source.counts().sent, source.device().health());
    finished.result?;
    tracing::info!(frames = sent, ?link, "camera stopped");
    Ok(())
}
