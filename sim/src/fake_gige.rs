//! A fake GigE Vision camera that shows the simulator's scene (for the GigE driver's tests,
//! the LiDAR robot profile's test and trying the driver by hand; never onboard): Aravis's own
//! fake camera ([`harvest_aravis::FakeCamera`], GVCP/GVSP on an interface) whose images are
//! the simulator's colour render of a scenario's orchard, seen from the scenario's colour camera
//! (the pose `sim/camera_calibration.toml` holds, the lens of `sim/gige_camera.toml`).
//!
//! The scene is rendered once at start (the world does not move: no simulated arm picks in front
//! of a fake camera) and every frame the camera sends is that render in the pixel format the
//! driver chose: RGB8 as is, Mono8 as luma, Bayer as the mosaic a colour sensor would sample.
//! A region smaller than 1920x1080 shows the render's top-left part; a larger one repeats its
//! edge.

use crate::orchard::World;
use crate::render_rgbd::RgbdRenderer;
use crate::scenario::Scenario;
use harvest_aravis::{Aravis, AravisError, FakeCamera, FakeImage, LoopbackCameraLock};
use harvest_hw::rgbd_camera::gige::PixelFormat;
use harvest_hw::rgbd_camera::gige::pixels::from_rgb;
use harvest_ipc::payloads::rgbd_frame::{RGB_BYTES, RGB_HEIGHT_PX, RGB_WIDTH_PX};

/// Why the fake could not start.
#[derive(Debug, thiserror::Error)]
pub enum FakeGigeError {
    /// Aravis is missing or the fake camera did not start.
    #[error(transparent)]
    Aravis(#[from] AravisError),
    /// The scene could not be made or rendered.
    #[error("scene: {0}")]
    Scene(String),
    /// The loopback lock could not be taken.
    #[error("loopback camera lock: {0}")]
    Lock(#[from] std::io::Error),
}

/// How the fake camera is set up.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FakeGigeConfig {
    /// Interface name or address the camera serves on.
    pub interface: String,
    /// Serial number (device id `Aravis-<serial>`).
    pub serial: String,
    /// Scenario preset of the scene and its seed.
    pub scenario: String,
    /// World seed.
    pub seed: u64,
}

impl FakeGigeConfig {
    /// On 127.0.0.1, serial `HVSIM`, the `default` scenario with seed 1 (the scene
    /// `harvest-fake-mid70` scans by default).
    pub fn loopback() -> Self {
        Self {
            interface: "127.0.0.1".into(),
            serial: "HVSIM".into(),
            scenario: "default".into(),
            seed: 1,
        }
    }
}

/// The running fake camera; stops when dropped.
pub struct FakeGige {
    _camera: FakeCamera,
    _lock: Option<LoopbackCameraLock>,
}

impl std::fmt::Debug for FakeGige {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FakeGige").finish_non_exhaustive()
    }
}

/// The render in one region size and pixel format, converted once and copied per frame.
#[derive(Default)]
struct Converted {
    /// (pixel format code, width, height) of `bytes`.
    key: Option<(u32, u32, u32)>,
    bytes: Vec<u8>,
}

/// Writes one frame of `render` (RGB8 1920x1080) into `image` in its pixel format.
fn fill_from_render(render: &[u8], converted: &mut Converted, image: &mut FakeImage<'_>) {
    let key = (image.pixel_format, image.width, image.height);
    if converted.key != Some(key) {
        let Some(format) = PixelFormat::from_code(image.pixel_format) else {
            return;
        };
        let (width, height) = (image.width as usize, image.height as usize);
        let mut region = vec![0u8; width * height * 3];
        for y in 0..height {
            let source_row = y.min(RGB_HEIGHT_PX - 1) * RGB_WIDTH_PX;
            for x in 0..width {
                let source = (source_row + x.min(RGB_WIDTH_PX - 1)) * 3;
                region[(y * width + x) * 3..][..3].copy_from_slice(&render[source..source + 3]);
            }
        }
        converted
            .bytes
            .resize(width * height * format.bytes_per_pixel(), 0);
        if let Err(error) = from_rgb(format, width, height, &region, &mut converted.bytes) {
            tracing::warn!(%error, "fake camera frame left as it was");
            return;
        }
        converted.key = Some(key);
    }
    if converted.bytes.len() == image.data.len() {
        image.data.copy_from_slice(&converted.bytes);
    }
}

impl FakeGige {
    /// Renders the scene and starts the camera. On loopback it first takes the host's
    /// [`LoopbackCameraLock`] (one fake at a time on 127.0.0.1:3956).
    pub fn start(config: &FakeGigeConfig) -> Result<Self, FakeGigeError> {
        let aravis = Aravis::load()?;
        let scenario = Scenario::preset(&config.scenario)
            .map_err(|error| FakeGigeError::Scene(error.to_string()))?;
        let world = World::generate(&scenario, config.seed)
            .map_err(|error| FakeGigeError::Scene(error.to_string()))?;
        let mut renderer = RgbdRenderer::new(&scenario.camera)
            .map_err(|error| FakeGigeError::Scene(error.to_string()))?;
        let mut render = vec![0u8; RGB_BYTES];
        renderer
            .render_color(&world, &mut render)
            .map_err(|error| FakeGigeError::Scene(error.to_string()))?;
        let lock = if config.interface.starts_with("127.") || config.interface == "lo" {
            Some(LoopbackCameraLock::acquire()?)
        } else {
            None
        };
        let mut camera = FakeCamera::start(&aravis, &config.interface, &config.serial)?;
        let mut converted = Converted::default();
        camera.set_fill(move |image| fill_from_render(&render, &mut converted, image));
        tracing::info!(
            interface = %config.interface,
            serial = %config.serial,
            scenario = %config.scenario,
            seed = config.seed,
            "fake GigE camera serving the simulator's render"
        );
        Ok(Self {
            _camera: camera,
            _lock: lock,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::rgbd_camera::gige::GigeConfig;

    #[test]
    fn the_fake_cameras_settings_hold_the_lens_its_renders_are_made_with() {
        let config: GigeConfig = harvest_ipc::config_file::parse_toml(
            include_str!("../gige_camera.toml"),
            "sim/gige_camera.toml",
            "GigE camera config",
        )
        .expect("parses");
        assert_eq!(config.problem(), None);
        let scenario = Scenario::preset("default").expect("scenario");
        let lens = scenario.camera.color_intrinsics();
        assert_eq!(
            (config.intrinsics.width_px, config.intrinsics.height_px),
            (1920, 1080)
        );
        for (name, ours, theirs) in [
            ("fx", config.intrinsics.fx_px, lens.fx_px),
            ("fy", config.intrinsics.fy_px, lens.fy_px),
            ("cx", config.intrinsics.cx_px, lens.cx_px),
            ("cy", config.intrinsics.cy_px, lens.cy_px),
        ] {
            assert!((ours - theirs).abs() < 1e-9, "{name}: {ours} vs {theirs}");
        }
        assert_eq!(config.intrinsics.distortion, lens.distortion);
    }

    #[test]
    fn a_region_is_converted_once_and_copied() {
        let render: Vec<u8> = (0..RGB_BYTES).map(|i| (i % 7) as u8 * 30).collect();
        let mut converted = Converted::default();
        let mut data = vec![0u8; 4 * 2 * 3];
        let mut image = FakeImage {
            data: &mut data,
            width: 4,
            height: 2,
            pixel_format: PixelFormat::RGB8.code(),
            frame_id: 1,
            timestamp_ns: 1,
            exposure_us: 1,
        };
        fill_from_render(&render, &mut converted, &mut image);
        assert_eq!(&data[..12], &render[..12]);
        assert_eq!(
            &data[12..],
            &render[RGB_WIDTH_PX * 3..RGB_WIDTH_PX * 3 + 12]
        );
        assert_eq!(converted.key, Some((PixelFormat::RGB8.code(), 4, 2)));
    }
}
