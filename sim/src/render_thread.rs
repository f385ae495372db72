//! The simulator's render thread: the devices whose output takes tens of milliseconds to make.
//!
//! On its own iceoryx2 node and wait set (the process's main node: it sends the heartbeats),
//! from its own copy of the [`World`], brought to the physics thread's newest step before every
//! render ([`ThreadLink::sync_world`]):
//! - the ToF camera's RGB-D frames on `hw/camera/rgbd` at the camera's frame rate, each stamped
//!   with the time its render started (the exposure; the world it shows is at most one physics
//!   period older);
//! - the ALACS unit's answers on `hw/alacs/image` to each `hw/alacs/command` (a capture renders
//!   its camera image, about 0.3 s, during which the camera waits: one render thread);
//! - with a LiDAR, its point frames on `hw/lidar/points` (see [`crate::lidar_device`]);
//! - the process heartbeat: `Running` while the physics thread keeps stepping, `Degraded` when
//!   it took no step since the previous heartbeat.
//!
//! The camera's renderer is a [`CameraRenderer`]: [`RgbdCamera`] (the scenario's ToF camera,
//! [`RgbdRenderer`]) in the process, a stand-in in tests.

use crate::alacs_device::{AlacsDeviceConfig, AlacsDeviceServer};
use crate::lidar_device::{LidarDeviceConfig, LidarDeviceError, LidarDevicePort};
use crate::orchard::World;
use crate::render_rgbd::{RenderError, RgbdRenderer};
use crate::scenario::CameraConfig;
use crate::thread_link::ThreadLink;
use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::catalogue::{HW_ALACS_COMMAND, HW_ALACS_IMAGE, HW_CAMERA_RGBD};
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::{ProcessRunState, RgbdFrame};
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter,
};
use std::time::{Duration, Instant};

/// Renders one frame of the simulated ToF camera.
pub trait CameraRenderer {
    /// Writes the RGB and depth images and the metadata (`frame.meta`) of frame `frame_seq`
    /// of `world` into `frame`; the header is the caller's.
    fn render(
        &mut self,
        world: &World,
        frame_seq: u64,
        frame: &mut RgbdFrame,
    ) -> Result<(), RenderError>;
}

/// The scenario's ToF camera: [`RgbdRenderer`]'s colour and depth images with their
/// intrinsics and registration.
pub struct RgbdCamera {
    renderer: RgbdRenderer,
    color_from_depth: RigidTransform,
}

impl RgbdCamera {
    /// Exposure reported in each frame's metadata, us.
    pub const EXPOSURE_US: u32 = 10_000;

    /// The camera of a scenario.
    pub fn new(camera: &CameraConfig) -> Result<Self, RenderError> {
        let renderer = RgbdRenderer::new(camera)?;
        let color_from_depth = renderer
            .robot_from_color()
            .inverse()
            .compose(&renderer.robot_from_depth());
        Ok(Self {
            renderer,
            color_from_depth,
        })
    }

    /// The renderer behind the camera (poses, intrinsics, label images).
    pub fn renderer(&mut self) -> &mut RgbdRenderer {
        &mut self.renderer
    }
}

impl CameraRenderer for RgbdCamera {
    fn render(
        &mut self,
        world: &World,
        frame_seq: u64,
        frame: &mut RgbdFrame,
    ) -> Result<(), RenderError> {
        self.renderer.render_color(world, &mut frame.rgb)?;
        self.renderer
            .render_depth(world, frame_seq, &mut frame.depth_mm)?;
        frame.meta.rgb_intrinsics = *self.renderer.color_intrinsics();
        frame.meta.depth_intrinsics = *self.renderer.depth_intrinsics();
        frame.meta.color_from_depth = self.color_from_depth;
        frame.meta.exposure_us = Self::EXPOSURE_US;
        frame.meta.flags = 0;
        Ok(())
    }
}

/// Settings of the render thread.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderThreadConfig {
    /// Name of the thread's iceoryx2 node; also the name in its heartbeats.
    pub node_name: String,
    /// Frame period of the ToF camera.
    pub camera_period: Duration,
    /// The simulated ALACS unit.
    pub alacs: AlacsDeviceConfig,
    /// The simulated LiDAR, if the robot carries one.
    pub lidar: Option<LidarDeviceConfig>,
}

/// Why the render thread stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum RenderThreadError {
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The camera renderer failed.
    #[error("camera frame {frame_seq}: {source}")]
    Camera {
        /// The frame being rendered.
        frame_seq: u64,
        /// The renderer's error.
        source: RenderError,
    },
    /// The ALACS unit could not be set up.
    #[error(transparent)]
    Alacs(#[from] harvest_hw::alacs::AlacsError),
    /// The LiDAR failed.
    #[error(transparent)]
    Lidar(#[from] LidarDeviceError),
}

harvest_ipc::from_ipc_errors!(RenderThreadError);

/// Runs the render thread until SIGINT/SIGTERM or [`ThreadLink::request_stop`]. `world` is the
/// thread's copy of the world the link was made from. Its node and ports are made here, on the
/// calling thread.
pub fn run(
    domain: &Domain,
    config: &RenderThreadConfig,
    mut world: World,
    camera: &mut impl CameraRenderer,
    link: &ThreadLink,
) -> Result<(), RenderThreadError> {
    let context = Context::new(domain, &config.node_name)?;
    let mut camera_out = context.publisher(HW_CAMERA_RGBD)?;
    let mut alacs = AlacsDeviceServer::new(config.alacs)?;
    let alacs_commands = context.subscriber(HW_ALACS_COMMAND)?;
    let mut alacs_images = context.publisher(HW_ALACS_IMAGE)?;
    let mut lidar = config
        .lidar
        .map(|lidar| LidarDevicePort::open(&context, lidar))
        .transpose()?;
    let mut health = HealthReporter::new(&context)?;
    let waiter = Waiter::new()?;
    let camera_tick = waiter.attach_interval(config.camera_period)?;
    let heartbeat_tick = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let alacs_guard = waiter.attach_listener(alacs_commands.listener())?;
    let lidar_tick = lidar
        .as_ref()
        .map(|lidar| waiter.attach_interval(lidar.period()))
        .transpose()?;
    let mut render_ns_total = 0u64;
    let mut physics_ticks_at_heartbeat = link.physics_ticks();
    tracing::info!(node = %config.node_name, "render thread running");
    let end = waiter
        .run(|attachment| -> Result<Flow, RenderThreadError> {
            if link.stop_requested() {
                return Ok(Flow::Stop);
            }
            if attachment.has_event_from(&camera_tick) {
                let started = Instant::now();
                let capture_ns = MonotonicClock::read_ns();
                let world_at = link.sync_world(&mut world);
                let mut frame = camera_out.loan()?;
                let frame_seq = camera_out.last_seq() + 1;
                camera
                    .render(&world, frame_seq, &mut frame)
                    .map_err(|source| RenderThreadError::Camera { frame_seq, source })?;
                frame.header.capture_ns = capture_ns;
                camera_out.send(frame)?;
                let render_ns = started.elapsed().as_nanos() as u64;
                render_ns_total += render_ns;
                tracing::trace!(
                    frame_seq,
                    render_ns,
                    physics_tick = world_at.physics_tick,
                    world_age_ns = capture_ns.saturating_sub(world_at.stamp_ns),
                    "frame rendered"
                );
            }
            if attachment.has_event_from(&alacs_guard) {
                while let Some(command) = alacs_commands.receive()? {
                    link.sync_world(&mut world);
                    let mut image = alacs_images.loan()?;
                    alacs.handle(&world, &command, &mut image);
                    alacs_images.send(image)?;
                }
            }
            if let (Some(lidar), Some(tick)) = (lidar.as_mut(), lidar_tick.as_ref())
                && attachment.has_event_from(tick)
            {
                link.sync_world(&mut world);
                lidar.tick(&world)?;
            }
            if attachment.has_event_from(&heartbeat_tick) {
                let frames = camera_out.last_seq();
                let mean_render_us = render_ns_total
                    .checked_div(frames)
                    .map_or(0, |ns| ns / 1000);
                let physics_ticks = link.physics_ticks();
                let state = if physics_ticks > physics_ticks_at_heartbeat {
                    ProcessRunState::Running
                } else {
                    tracing::warn!(
                        physics_ticks,
                        "the physics thread took no step since the last heartbeat"
                    );
                    ProcessRunState::Degraded
                };
                physics_ticks_at_heartbeat = physics_ticks;
                health.report(state, frames, "render_us", mean_render_us)?;
            }
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    tracing::info!(
        ?end,
        frames = camera_out.last_seq(),
        "render thread stopped"
    );
    Ok(())
}
