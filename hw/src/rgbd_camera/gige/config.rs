//! The GigE Vision camera's settings (`harvest camera --device gige --config FILE`): which
//! camera, its pixel format, rate and exposure, the link's packet size, and the lens's
//! calibrated intrinsics. Read as TOML with unknown keys refused; [`GigeConfig::problem`]
//! checks the values.

use super::pixels::PixelFormat;
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};

/// Buffers queued for the stream when the file does not say.
pub const DEFAULT_BUFFERS: usize = 4;

fn default_buffers() -> usize {
    DEFAULT_BUFFERS
}

/// How to run a GigE Vision camera.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct GigeConfig {
    /// The camera to open: its Aravis device id (`<vendor>-<serial>`), serial number or IP
    /// address; none: the first camera found (`--camera-id` overrides).
    #[serde(default)]
    pub camera_id: Option<String>,
    /// The pixel format the camera sends (`Mono8`, `BayerRG8`, `BayerGR8`, `BayerGB8`,
    /// `BayerBG8`, `RGB8`); the driver converts it to the frame's RGB8.
    pub pixel_format: PixelFormat,
    /// Acquisition frame rate, frames per second.
    pub frame_rate_hz: f64,
    /// A fixed exposure time, microseconds (automatic exposure is turned off); none: the
    /// camera's own setting stays.
    #[serde(default)]
    pub exposure_us: Option<f64>,
    /// Stream packet size, bytes (e.g. 8000 with jumbo frames on the camera's link); none:
    /// negotiated with the camera's test packets where it has them.
    #[serde(default)]
    pub packet_size_bytes: Option<u32>,
    /// Offset of the 1920x1080 region on the sensor, pixels (x, y); none: centred.
    #[serde(default)]
    pub region_offset_px: Option<[u32; 2]>,
    /// Buffers queued for the stream (2-64).
    #[serde(default = "default_buffers")]
    pub buffers: usize,
    /// The calibrated intrinsics of the camera with its lens, at 1920x1080.
    pub intrinsics: CameraIntrinsics,
}

impl GigeConfig {
    /// What makes the settings unusable, naming the key and value; None when they are fine.
    pub fn problem(&self) -> Option<String> {
        if !(self.frame_rate_hz.is_finite() && self.frame_rate_hz > 0.0) {
            return Some(format!(
                "frame_rate_hz = {} is not a positive number",
                self.frame_rate_hz
            ));
        }
        if let Some(exposure_us) = self.exposure_us
            && !(exposure_us.is_finite() && exposure_us > 0.0)
        {
            return Some(format!(
                "exposure_us = {exposure_us} is not a positive number"
            ));
        }
        if !(2..=64).contains(&self.buffers) {
            return Some(format!("buffers = {} is outside 2..=64", self.buffers));
        }
        if let Some(bytes) = self.packet_size_bytes
            && !(576..=16_384).contains(&bytes)
        {
            return Some(format!(
                "packet_size_bytes = {bytes} is outside 576..=16384"
            ));
        }
        let size = (
            self.intrinsics.width_px as usize,
            self.intrinsics.height_px as usize,
        );
        if size != (RGB_WIDTH_PX, RGB_HEIGHT_PX) {
            return Some(format!(
                "intrinsics are {}x{} px; frames are {RGB_WIDTH_PX}x{RGB_HEIGHT_PX}",
                size.0, size.1
            ));
        }
        self.intrinsics.problem()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FILE: &str = r#"
camera_id = "127.0.0.1"
pixel_format = "BayerRG8"
frame_rate_hz = 30.0
exposure_us = 8000.0
packet_size_bytes = 8000

[intrinsics]
width_px = 1920
height_px = 1080
fx_px = 1598.0
fy_px = 1598.0
cx_px = 959.5
cy_px = 539.5
distortion = [-0.04, 0.01, 0.0, 0.0, 0.0]
"#;

    #[test]
    fn a_file_parses_and_its_values_are_checked() {
        let config: GigeConfig =
            harvest_ipc::config_file::parse_toml(FILE, "gige.toml", "t").expect("parses");
        assert_eq!(config.pixel_format, PixelFormat::BayerRG8);
        assert_eq!(config.buffers, DEFAULT_BUFFERS);
        assert_eq!(config.problem(), None);
        let mut bad = config.clone();
        bad.frame_rate_hz = 0.0;
        assert!(bad.problem().expect("refused").contains("frame_rate_hz"));
        let mut bad = config.clone();
        bad.intrinsics.width_px = 1280;
        assert!(bad.problem().expect("refused").contains("1280x1080"));
        let unknown = harvest_ipc::config_file::parse_toml::<GigeConfig>(
            &FILE.replace("frame_rate_hz", "rate_hz"),
            "gige.toml",
            "t",
        )
        .expect_err("unknown key");
        assert!(unknown.to_string().contains("rate_hz"), "{unknown}");
        let format = harvest_ipc::config_file::parse_toml::<GigeConfig>(
            &FILE.replace("BayerRG8", "YUV422"),
            "gige.toml",
            "t",
        )
        .expect_err("unknown format");
        assert!(format.to_string().contains("YUV422"), "{format}");
    }
}
