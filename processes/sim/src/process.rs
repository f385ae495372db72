//! `harvest sim`: the simulated robot as hardware. Owns the world and serves the device
//! channels the drivers in the other processes talk to, as real devices would over USB/serial:
//! the ToF camera's frames on `hw/camera/rgbd` at the camera's frame rate.
//!
//! The loop is one wait set: each device has an interval at its own period (the simulated
//! device's clock) and the loop sleeps in between.

use crate::orchard::World;
use crate::render_rgbd::RgbdRenderer;
use crate::scenario::Scenario;
use harvest_ipc::catalogue::HW_CAMERA_RGBD;
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter,
};
use std::path::Path;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, clap::Args)]
pub struct SimArgs {
    /// Scenario preset name (`default`, `ideal`, ...) or path to a scenario TOML file.
    #[arg(long, default_value = "default")]
    pub scenario: String,
    /// World seed (apples, leaves, noise, failures).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Frame rate of the simulated ToF camera.
    #[arg(long, default_value_t = 30.0)]
    pub camera_rate_hz: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    #[error(transparent)]
    Orchard(#[from] crate::orchard::OrchardError),
    #[error(transparent)]
    Render(#[from] crate::render_rgbd::RenderError),
    #[error(transparent)]
    Node(#[from] harvest_ipc::error::NodeError),
    #[error(transparent)]
    Channel(#[from] harvest_ipc::error::OpenChannelError),
    #[error(transparent)]
    Send(#[from] harvest_ipc::error::SendError),
    #[error(transparent)]
    Wait(#[from] harvest_ipc::error::WaitError),
    #[error("camera rate must be between 0.1 and 120 Hz, got {0}")]
    BadRate(f64),
}

/// Loads a scenario by preset name, or from a file when the argument is a path to one.
pub fn load_scenario(name_or_path: &str) -> Result<Scenario, crate::scenario::ScenarioError> {
    let path = Path::new(name_or_path);
    if name_or_path.ends_with(".toml") || path.is_file() {
        Scenario::from_file(path)
    } else {
        Scenario::preset(name_or_path)
    }
}

/// Runs the simulator until SIGINT/SIGTERM.
pub fn run(args: &SimArgs, domain: &Domain, process_name: &str) -> Result<(), SimError> {
    if !(0.1..=120.0).contains(&args.camera_rate_hz) {
        return Err(SimError::BadRate(args.camera_rate_hz));
    }
    let scenario = load_scenario(&args.scenario)?;
    let world = World::generate(&scenario, args.seed)?;
    let mut renderer = RgbdRenderer::new(&scenario.camera)?;
    let context = Context::new(domain, process_name)?;
    let mut camera_out = context.publisher(HW_CAMERA_RGBD)?;
    let mut health = HealthReporter::new(&context)?;
    let waiter = Waiter::new()?;
    let camera_tick = waiter.attach_interval(Duration::from_secs_f64(1.0 / args.camera_rate_hz))?;
    let heartbeat_tick = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let color_from_depth = renderer
        .robot_from_color()
        .inverse()
        .compose(&renderer.robot_from_depth());
    tracing::info!(
        scenario = %args.scenario,
        seed = args.seed,
        apples = world.apples().len(),
        camera_rate_hz = args.camera_rate_hz,
        "simulated robot running"
    );
    let mut render_ns_total = 0u64;
    waiter
        .run(|attachment| -> Result<Flow, SimError> {
            if attachment.has_event_from(&camera_tick) {
                let started = Instant::now();
                let capture_ns = MonotonicClock::read_ns();
                let mut frame = camera_out.loan()?;
                let frame_seq = camera_out.last_seq() + 1;
                renderer.render_color(&world, &mut frame.rgb)?;
                renderer.render_depth(&world, frame_seq, &mut frame.depth_mm)?;
                frame.meta.rgb_intrinsics = *renderer.color_intrinsics();
                frame.meta.depth_intrinsics = *renderer.depth_intrinsics();
                frame.meta.color_from_depth = color_from_depth;
                frame.meta.exposure_us = 10_000;
                frame.meta.flags = 0;
                frame.header.capture_ns = capture_ns;
                camera_out.send(frame)?;
                let render_ns = started.elapsed().as_nanos() as u64;
                render_ns_total += render_ns;
                tracing::trace!(frame_seq, render_ns, "frame rendered");
            }
            if attachment.has_event_from(&heartbeat_tick) {
                let frames = camera_out.last_seq();
                let mean_render_us = if frames == 0 {
                    0
                } else {
                    render_ns_total / frames / 1000
                };
                health.report(
                    ProcessRunState::Running,
                    frames,
                    "render_us",
                    mean_render_us,
                )?;
            }
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    tracing::info!(frames = camera_out.last_seq(), "simulator stopped");
    Ok(())
}
