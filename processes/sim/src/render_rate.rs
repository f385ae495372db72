//! Measures how many frames per second [`RgbdRenderer`] renders on the calling thread.
//!
//! A measurement, never an assertion: run it in a release build, e.g.
//! `cargo run --release -p harvest-sim --example render_rate -- default 60`.

use std::time::Instant;

use crate::orchard::{OrchardError, World};
use crate::render_rgbd::{RenderError, RgbdRenderer};
use crate::scenario::Scenario;

/// Frames per second of each kind of frame, single thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderRate {
    pub frames: u32,
    /// RGB 1920x1080 alone.
    pub color_fps: f64,
    /// Depth 640x480 (with noise) alone.
    pub depth_fps: f64,
    /// One RGB plus one depth frame.
    pub rgbd_fps: f64,
}

/// Why a measurement could not run.
#[derive(Debug, thiserror::Error)]
pub enum RenderRateError {
    #[error("world generation: {0}")]
    Orchard(#[from] OrchardError),
    #[error("rendering: {0}")]
    Render(#[from] RenderError),
}

/// Renders `frames` frames of each kind of the world of `scenario` and `seed` and times them.
pub fn measure_render_rate(
    scenario: &Scenario,
    seed: u64,
    frames: u32,
) -> Result<RenderRate, RenderRateError> {
    let world = World::generate(scenario, seed)?;
    let mut renderer = RgbdRenderer::new(&scenario.camera)?;
    let color = *renderer.color_intrinsics();
    let depth = *renderer.depth_intrinsics();
    let mut rgb = vec![0u8; 3 * (color.width_px * color.height_px) as usize];
    let mut depth_mm = vec![0u16; (depth.width_px * depth.height_px) as usize];
    let frames = frames.max(1);
    // One warm-up frame of each so page faults are not timed.
    renderer.render_color(&world, &mut rgb)?;
    renderer.render_depth(&world, 0, &mut depth_mm)?;
    let start = Instant::now();
    for _ in 0..frames {
        renderer.render_color(&world, &mut rgb)?;
    }
    let color_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    for frame_seq in 0..u64::from(frames) {
        renderer.render_depth(&world, frame_seq, &mut depth_mm)?;
    }
    let depth_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    for frame_seq in 0..u64::from(frames) {
        renderer.render_color(&world, &mut rgb)?;
        renderer.render_depth(&world, frame_seq, &mut depth_mm)?;
    }
    let rgbd_s = start.elapsed().as_secs_f64();
    let per_second = |seconds: f64| f64::from(frames) / seconds.max(f64::MIN_POSITIVE);
    Ok(RenderRate {
        frames,
        color_fps: per_second(color_s),
        depth_fps: per_second(depth_s),
        rgbd_fps: per_second(rgbd_s),
    })
}
