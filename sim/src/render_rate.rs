//! Measures how many frames per second [`RgbdRenderer`] renders on the calling thread.
//!
//! A measurement, never an assertion: run it in a release build, e.g.
//! `cargo run --release -p harvest-sim --example render_rate -- default 60`.
//! Two figures per frame kind: frames per wall-clock second (what this machine gave, other load
//! included) and frames per second of this thread's CPU time (what one dedicated core gives).

use std::time::Instant;

use nix::time::{ClockId, clock_gettime};

use crate::orchard::{OrchardError, World};
use crate::render_rgbd::{RenderError, RgbdRenderer};
use crate::scenario::Scenario;

/// Frames per second of one kind of frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rate {
    /// Frames per wall-clock second.
    pub wall_fps: f64,
    /// Frames per second of the rendering thread's CPU time (one dedicated core).
    pub cpu_fps: f64,
}

/// Rates of each kind of frame, single thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderRate {
    pub frames: u32,
    /// RGB 1920x1080 alone.
    pub color: Rate,
    /// Depth 640x480 (with noise) alone.
    pub depth: Rate,
    /// One RGB plus one depth frame.
    pub rgbd: Rate,
}

/// Why a measurement could not run.
#[derive(Debug, thiserror::Error)]
pub enum RenderRateError {
    #[error("world generation: {0}")]
    Orchard(#[from] OrchardError),
    #[error("rendering: {0}")]
    Render(#[from] RenderError),
    /// The thread CPU clock could not be read.
    #[error("reading CLOCK_THREAD_CPUTIME_ID: {0}")]
    CpuClock(#[from] nix::Error),
}

fn thread_cpu_s() -> Result<f64, nix::Error> {
    let now = clock_gettime(ClockId::CLOCK_THREAD_CPUTIME_ID)?;
    Ok(now.tv_sec() as f64 + now.tv_nsec() as f64 * 1e-9)
}

/// Runs `render` `frames` times (with the frame number) and times it.
fn time_frames(
    frames: u32,
    mut render: impl FnMut(u64) -> Result<(), RenderError>,
) -> Result<Rate, RenderRateError> {
    let wall = Instant::now();
    let cpu = thread_cpu_s()?;
    for frame_seq in 0..u64::from(frames) {
        render(frame_seq)?;
    }
    let cpu_s = thread_cpu_s()? - cpu;
    let wall_s = wall.elapsed().as_secs_f64();
    let per_second = |seconds: f64| f64::from(frames) / seconds.max(f64::MIN_POSITIVE);
    Ok(Rate {
        wall_fps: per_second(wall_s),
        cpu_fps: per_second(cpu_s),
    })
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
    let color_rate = time_frames(frames, |_| renderer.render_color(&world, &mut rgb))?;
    let depth_rate = time_frames(frames, |frame_seq| {
        renderer.render_depth(&world, frame_seq, &mut depth_mm)
    })?;
    let rgbd_rate = time_frames(frames, |frame_seq| {
        renderer.render_color(&world, &mut rgb)?;
        renderer.render_depth(&world, frame_seq, &mut depth_mm)
    })?;
    Ok(RenderRate {
        frames,
        color: color_rate,
        depth: depth_rate,
        rgbd: rgbd_rate,
    })
}
