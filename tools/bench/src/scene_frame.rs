//! One rendered frame of a scenario (world seed 1): the colour image (and, for the benchmarks
//! that send it, the depth image) the simulator's camera would give, for the benchmarks that
//! need realistic pixels (a detector, an encoder, a JPEG over the remote link) rather than blank
//! frames.

use harvest_ipc::payloads::rgbd_frame::DEPTH_PIXELS;
use harvest_sim::process::load_scenario;
use harvest_sim::{RgbdRenderer, World};

/// A scenario's first world's colour image, rendered once.
pub struct SceneFrame {
    pub width_px: usize,
    pub height_px: usize,
    /// Interleaved RGB, `width_px * height_px * 3` bytes.
    pub rgb: Vec<u8>,
}

/// Why the frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum SceneFrameError {
    #[error("scenario {0}")]
    Scenario(String),
    #[error("render: {0}")]
    Render(String),
}

impl SceneFrame {
    /// Renders `scenario` (a preset name or a file) as its camera's colour sensor sees world
    /// seed 1.
    pub fn render(scenario: &str) -> Result<Self, SceneFrameError> {
        Ok(Self::render_colour(scenario)?.0)
    }

    /// The same, with the ToF depth image (millimetres) of the same world.
    pub fn render_with_depth(scenario: &str) -> Result<(Self, Vec<u16>), SceneFrameError> {
        let (frame, world, mut renderer) = Self::render_colour(scenario)?;
        let mut depth_mm = vec![0u16; DEPTH_PIXELS];
        renderer
            .render_depth(&world, 1, &mut depth_mm)
            .map_err(|e| render_error(&e))?;
        Ok((frame, depth_mm))
    }

    /// The colour frame, with the world and the renderer that made it.
    fn render_colour(scenario: &str) -> Result<(Self, World, RgbdRenderer), SceneFrameError> {
        let scenario =
            load_scenario(scenario).map_err(|e| SceneFrameError::Scenario(e.to_string()))?;
        let world = World::generate(&scenario, 1).map_err(|e| render_error(&e))?;
        let mut renderer = RgbdRenderer::new(&scenario.camera).map_err(|e| render_error(&e))?;
        let intrinsics = *renderer.color_intrinsics();
        let (width_px, height_px) = (intrinsics.width_px as usize, intrinsics.height_px as usize);
        let mut rgb = vec![0u8; width_px * height_px * 3];
        renderer
            .render_color(&world, &mut rgb)
            .map_err(|e| render_error(&e))?;
        let frame = Self {
            width_px,
            height_px,
            rgb,
        };
        Ok((frame, world, renderer))
    }
}

fn render_error(error: &dyn std::fmt::Display) -> SceneFrameError {
    SceneFrameError::Render(error.to_string())
}
