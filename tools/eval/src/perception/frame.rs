//! Simulated camera frames in the camera's wire format: the [`RgbdFrame`] the perception process
//! receives, rendered by the simulator exactly as `harvest sim` fills a loaned frame.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::RgbdFrame;
use harvest_sim::render_thread::{CameraRenderer, RgbdCamera};
use harvest_sim::scenario::CameraConfig;
use harvest_sim::{RenderError, World};

/// Nominal frame period used for the capture stamps (30 Hz).
const FRAME_PERIOD_NS: u64 = 33_333_333;

/// A zeroed [`RgbdFrame`] on the heap (6.8 MB: too large for the stack).
pub fn zeroed_frame() -> Box<RgbdFrame> {
    harvest_ipc::payload::boxed_zeroed()
}

/// The simulator's ToF camera ([`RgbdCamera`], what `harvest sim` renders into a loaned frame)
/// plus the capture stamps of a 30 Hz stream.
pub struct FrameRenderer {
    camera: RgbdCamera,
}

impl FrameRenderer {
    pub fn new(camera: &CameraConfig) -> Result<Self, RenderError> {
        Ok(Self {
            camera: RgbdCamera::new(camera)?,
        })
    }

    /// True pose of the colour sensor in the robot frame.
    pub fn robot_from_color(&mut self) -> RigidTransform {
        self.camera.renderer().robot_from_color()
    }

    pub fn color_intrinsics(&mut self) -> CameraIntrinsics {
        *self.camera.renderer().color_intrinsics()
    }

    /// Renders colour and depth of `world` into `frame` with sequence number `frame_seq` (which
    /// also seeds the depth noise), and the metadata and stamps of the simulated camera.
    pub fn render(
        &mut self,
        world: &World,
        frame_seq: u64,
        frame: &mut RgbdFrame,
    ) -> Result<(), RenderError> {
        self.camera.render(world, frame_seq, frame)?;
        frame.header.msg_seq = frame_seq;
        frame.header.capture_ns = frame_seq * FRAME_PERIOD_NS;
        frame.header.publish_ns = frame.header.capture_ns;
        Ok(())
    }

    /// Renders the per-pixel labels of `world` at colour resolution.
    pub fn render_labels(&mut self, world: &World, labels: &mut [u32]) -> Result<(), RenderError> {
        self.camera.renderer().render_labels(world, labels)
    }
}
