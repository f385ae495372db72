//! Simulated camera frames in the camera's wire format: the [`RgbdFrame`] the perception process
//! receives, rendered by the simulator exactly as `harvest sim` fills a loaned frame.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::{RgbdFrame, RgbdFrameMeta};
use harvest_sim::scenario::CameraConfig;
use harvest_sim::{RenderError, RgbdRenderer, World};

/// Exposure written into the frame metadata, as the simulated camera device does.
const EXPOSURE_US: u32 = 10_000;
/// Nominal frame period used for the capture stamps (30 Hz).
const FRAME_PERIOD_NS: u64 = 33_333_333;

/// A zeroed [`RgbdFrame`] on the heap (6.8 MB: too large for the stack).
pub fn zeroed_frame() -> Box<RgbdFrame> {
    harvest_ipc::payload::boxed_zeroed()
}

/// The simulator's RGB-D renderer plus the frame metadata the simulated camera sends.
#[derive(Debug)]
pub struct FrameRenderer {
    renderer: RgbdRenderer,
    meta: RgbdFrameMeta,
}

impl FrameRenderer {
    pub fn new(camera: &CameraConfig) -> Result<Self, RenderError> {
        let renderer = RgbdRenderer::new(camera)?;
        let color_from_depth = renderer
            .robot_from_color()
            .inverse()
            .compose(&renderer.robot_from_depth());
        let meta = RgbdFrameMeta {
            rgb_intrinsics: *renderer.color_intrinsics(),
            depth_intrinsics: *renderer.depth_intrinsics(),
            color_from_depth,
            exposure_us: EXPOSURE_US,
            flags: 0,
        };
        Ok(Self { renderer, meta })
    }

    /// True pose of the colour sensor in the robot frame.
    pub fn robot_from_color(&self) -> RigidTransform {
        self.renderer.robot_from_color()
    }

    pub fn color_intrinsics(&self) -> CameraIntrinsics {
        *self.renderer.color_intrinsics()
    }

    /// Renders colour and depth of `world` into `frame` with sequence number `frame_seq` (which
    /// also seeds the depth noise), and the metadata and stamps of the simulated camera.
    pub fn render(
        &mut self,
        world: &World,
        frame_seq: u64,
        frame: &mut RgbdFrame,
    ) -> Result<(), RenderError> {
        self.renderer.render_color(world, &mut frame.rgb)?;
        self.renderer
            .render_depth(world, frame_seq, &mut frame.depth_mm)?;
        frame.meta = self.meta;
        frame.header.msg_seq = frame_seq;
        frame.header.capture_ns = frame_seq * FRAME_PERIOD_NS;
        frame.header.publish_ns = frame.header.capture_ns;
        Ok(())
    }

    /// Renders the per-pixel labels of `world` at colour resolution.
    pub fn render_labels(&mut self, world: &World, labels: &mut [u32]) -> Result<(), RenderError> {
        self.renderer.render_labels(world, labels)
    }
}
