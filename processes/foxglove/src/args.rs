//! The command line of `harvest foxglove`.

use harvest_foxglove_mapping::{ImageSettings, ViewingRates};
use std::net::SocketAddr;
use std::path::PathBuf;

/// Environment variable that sets `--listen` (tests and a second stack on one host use it to
/// pick another port without editing the launch file).
pub const LISTEN_ENV: &str = "HARVEST_FOXGLOVE_LISTEN";

/// Options of `harvest foxglove`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct FoxgloveArgs {
    /// Address the WebSocket server listens on. The default only accepts connections from this
    /// host; `0.0.0.0:8765` exposes it to the network (no authentication: trusted networks only).
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8765", env = LISTEN_ENV)]
    pub listen: SocketAddr,
    /// Camera images per second sent to clients (JPEG-encoded on a thread of their own).
    #[arg(long, default_value_t = ViewingRates::VIEWING.camera_hz)]
    pub camera_rate_hz: f64,
    /// Arm and vacuum states per second sent to clients (200 Hz in the stack).
    #[arg(long, default_value_t = ViewingRates::VIEWING.state_hz)]
    pub state_rate_hz: f64,
    /// Integer factor the camera image is downscaled by (1: full 1920x1080).
    #[arg(long, default_value_t = ImageSettings::VIEWING.scale)]
    pub image_scale: u32,
    /// JPEG quality of the camera image, 1-100.
    #[arg(long, default_value_t = ImageSettings::VIEWING.jpeg_quality)]
    pub jpeg_quality: u8,
    /// Camera calibration file (`robot_from_camera`, as perception reads it): places the camera
    /// on the robot in the 3D view.
    #[arg(long, value_name = "PATH")]
    pub calibration: Option<PathBuf>,
    /// LiDAR extrinsic file (`camera_from_lidar`): places the LiDAR cloud in the 3D view.
    #[arg(long, value_name = "PATH")]
    pub lidar_extrinsic: Option<PathBuf>,
    /// Messages queued per client before the oldest are dropped (a slow client loses messages,
    /// it never slows the bridge). About 1 s at the default rates.
    #[arg(long, default_value_t = 128)]
    pub client_backlog: usize,
}

impl Default for FoxgloveArgs {
    fn default() -> Self {
        Self {
            listen: SocketAddr::from(([127, 0, 0, 1], 8765)),
            camera_rate_hz: ViewingRates::VIEWING.camera_hz,
            state_rate_hz: ViewingRates::VIEWING.state_hz,
            image_scale: ImageSettings::VIEWING.scale,
            jpeg_quality: ImageSettings::VIEWING.jpeg_quality,
            calibration: None,
            lidar_extrinsic: None,
            client_backlog: 128,
        }
    }
}

impl FoxgloveArgs {
    pub fn rates(&self) -> ViewingRates {
        ViewingRates {
            camera_hz: self.camera_rate_hz,
            state_hz: self.state_rate_hz,
        }
    }

    pub fn image(&self) -> ImageSettings {
        ImageSettings {
            scale: self.image_scale,
            jpeg_quality: self.jpeg_quality,
        }
    }

    /// The problem with these options, if any, naming the option.
    pub fn problem(&self) -> Option<String> {
        if let Some(problem) = self.rates().problem() {
            return Some(format!("--camera-rate-hz / --state-rate-hz: {problem}"));
        }
        if let Some(problem) = self.image().problem() {
            return Some(format!("--image-scale / --jpeg-quality: {problem}"));
        }
        if !(1..=100_000).contains(&self.client_backlog) {
            return Some(format!(
                "--client-backlog {} is not in 1..=100000",
                self.client_backlog
            ));
        }
        None
    }
}
