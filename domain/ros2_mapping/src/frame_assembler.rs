//! Colour and depth images of a bag into the stack's RGB-D frames: each colour image is paired
//! with the depth image nearest in stamp, when they differ by at most the map's tolerance, and
//! the pair becomes one frame with the latest camera models. Images that find no partner are
//! dropped and counted, as are those before the first camera models.
//!
//! Stamps only increase within one topic of a bag, so a decision is made as soon as it cannot
//! change: an image older than the other queue's oldest minus the tolerance has no partner left.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::rgbd_frame::{DEPTH_PIXELS, RGB_BYTES};
use harvest_ipc::payloads::{RgbdFrame, RgbdFrameMeta};
use std::collections::VecDeque;

/// Images held while waiting for a partner, per stream; beyond it the oldest is dropped.
const QUEUE_LIMIT: usize = 4;

/// Why images were dropped.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AssemblyCounts {
    pub frames: u64,
    /// Colour images without a depth image within the tolerance.
    pub unpaired_color: u64,
    pub unpaired_depth: u64,
    /// Pairs dropped because no camera models had been seen yet.
    pub before_camera_info: u64,
}

/// Pairs colour and depth by stamp.
#[derive(Debug)]
pub struct FrameAssembler {
    tolerance_ns: u64,
    color_from_depth: RigidTransform,
    color_info: Option<CameraIntrinsics>,
    depth_info: Option<CameraIntrinsics>,
    colors: VecDeque<(u64, Vec<u8>)>,
    depths: VecDeque<(u64, Vec<u16>)>,
    /// Buffers given back, reused for the next images.
    spare_colors: Vec<Vec<u8>>,
    spare_depths: Vec<Vec<u16>>,
    counts: AssemblyCounts,
}

impl FrameAssembler {
    pub fn new(tolerance_ns: u64, color_from_depth: RigidTransform) -> Self {
        Self {
            tolerance_ns,
            color_from_depth,
            color_info: None,
            depth_info: None,
            colors: VecDeque::new(),
            depths: VecDeque::new(),
            spare_colors: Vec::new(),
            spare_depths: Vec::new(),
            counts: AssemblyCounts::default(),
        }
    }

    pub fn counts(&self) -> AssemblyCounts {
        self.counts
    }

    pub fn set_color_info(&mut self, intrinsics: CameraIntrinsics) {
        self.color_info = Some(intrinsics);
    }

    pub fn set_depth_info(&mut self, intrinsics: CameraIntrinsics) {
        self.depth_info = Some(intrinsics);
    }

    /// A buffer for the next colour image (RGB8, the stack's size), to fill and hand to
    /// [`Self::push_color`].
    pub fn color_buffer(&mut self) -> Vec<u8> {
        self.spare_colors
            .pop()
            .unwrap_or_else(|| vec![0; RGB_BYTES])
    }

    /// A buffer for the next depth image (mm, the stack's size).
    pub fn depth_buffer(&mut self) -> Vec<u16> {
        self.spare_depths
            .pop()
            .unwrap_or_else(|| vec![0; DEPTH_PIXELS])
    }

    /// Takes a colour image captured at `stamp_ns`.
    pub fn push_color(&mut self, stamp_ns: u64, rgb: Vec<u8>) {
        self.colors.push_back((stamp_ns, rgb));
        if self.colors.len() > QUEUE_LIMIT
            && let Some((_, old)) = self.colors.pop_front()
        {
            self.counts.unpaired_color += 1;
            self.spare_colors.push(old);
        }
    }

    /// Takes a depth image captured at `stamp_ns`.
    pub fn push_depth(&mut self, stamp_ns: u64, depth_mm: Vec<u16>) {
        self.depths.push_back((stamp_ns, depth_mm));
        if self.depths.len() > QUEUE_LIMIT
            && let Some((_, old)) = self.depths.pop_front()
        {
            self.counts.unpaired_depth += 1;
            self.spare_depths.push(old);
        }
    }

    fn drop_color(&mut self) {
        if let Some((_, buffer)) = self.colors.pop_front() {
            self.counts.unpaired_color += 1;
            self.spare_colors.push(buffer);
        }
    }

    fn drop_depth(&mut self) {
        if let Some((_, buffer)) = self.depths.pop_front() {
            self.counts.unpaired_depth += 1;
            self.spare_depths.push(buffer);
        }
    }

    /// Writes the next complete frame into `frame` (header `capture_ns` = the colour image's
    /// stamp; `msg_seq` and `publish_ns` are the transport's) and returns true, or returns false
    /// when no pair is decided yet.
    pub fn next_frame(&mut self, frame: &mut RgbdFrame) -> bool {
        loop {
            let (Some(&(color_ns, _)), Some(&(depth_ns, _))) =
                (self.colors.front(), self.depths.front())
            else {
                return false;
            };
            if color_ns.saturating_add(self.tolerance_ns) < depth_ns {
                self.drop_color();
                continue;
            }
            if depth_ns.saturating_add(self.tolerance_ns) < color_ns {
                self.drop_depth();
                continue;
            }
            // Within the tolerance; a later depth image may be nearer still.
            if let Some(&(next_depth_ns, _)) = self.depths.get(1)
                && next_depth_ns.abs_diff(color_ns) < depth_ns.abs_diff(color_ns)
            {
                self.drop_depth();
                continue;
            }
            if let Some(&(next_color_ns, _)) = self.colors.get(1)
                && next_color_ns.abs_diff(depth_ns) < color_ns.abs_diff(depth_ns)
            {
                self.drop_color();
                continue;
            }
            let (Some((_, rgb)), Some((_, depth))) =
                (self.colors.pop_front(), self.depths.pop_front())
            else {
                return false;
            };
            let emitted = match (self.color_info, self.depth_info) {
                (Some(color), Some(depth_info)) => {
                    frame.header.capture_ns = color_ns;
                    frame.meta = RgbdFrameMeta {
                        rgb_intrinsics: color,
                        depth_intrinsics: depth_info,
                        color_from_depth: self.color_from_depth,
                        exposure_us: 0,
                        flags: 0,
                    };
                    frame.rgb.copy_from_slice(&rgb);
                    frame.depth_mm.copy_from_slice(&depth);
                    self.counts.frames += 1;
                    true
                }
                _ => {
                    self.counts.before_camera_info += 1;
                    false
                }
            };
            self.spare_colors.push(rgb);
            self.spare_depths.push(depth);
            if emitted {
                return true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payload::boxed_zeroed;

    const MS: u64 = 1_000_000;

    fn assembler() -> FrameAssembler {
        let mut assembler = FrameAssembler::new(10 * MS, RigidTransform::IDENTITY);
        assembler.set_color_info(CameraIntrinsics::tl460_rgb());
        assembler.set_depth_info(CameraIntrinsics::tl460_depth());
        assembler
    }

    fn color(assembler: &mut FrameAssembler, stamp_ns: u64, value: u8) {
        let mut buffer = assembler.color_buffer();
        buffer[0] = value;
        assembler.push_color(stamp_ns, buffer);
    }

    fn depth(assembler: &mut FrameAssembler, stamp_ns: u64, value: u16) {
        let mut buffer = assembler.depth_buffer();
        buffer[0] = value;
        assembler.push_depth(stamp_ns, buffer);
    }

    #[test]
    fn pairs_by_nearest_stamp_within_the_tolerance() {
        let mut a = assembler();
        let mut frame = boxed_zeroed::<RgbdFrame>();
        // Depth at 95 and 102 ms, colour at 100 ms: the 102 ms depth is nearer.
        depth(&mut a, 95 * MS, 1);
        color(&mut a, 100 * MS, 7);
        depth(&mut a, 102 * MS, 2);
        assert!(a.next_frame(&mut frame));
        assert_eq!(frame.header.capture_ns, 100 * MS);
        assert_eq!((frame.rgb[0], frame.depth_mm[0]), (7, 2));
        assert_eq!(frame.meta.rgb_intrinsics, CameraIntrinsics::tl460_rgb());
        // A colour image 50 ms from any depth is dropped.
        color(&mut a, 150 * MS, 8);
        depth(&mut a, 200 * MS, 3);
        color(&mut a, 201 * MS, 9);
        assert!(a.next_frame(&mut frame));
        assert_eq!((frame.rgb[0], frame.depth_mm[0]), (9, 3));
        assert!(!a.next_frame(&mut frame));
        let counts = a.counts();
        assert_eq!(
            (counts.frames, counts.unpaired_color, counts.unpaired_depth),
            (2, 1, 1)
        );
    }

    #[test]
    fn no_frame_before_the_camera_models() {
        let mut a = FrameAssembler::new(10 * MS, RigidTransform::IDENTITY);
        let mut frame = boxed_zeroed::<RgbdFrame>();
        color(&mut a, 100 * MS, 1);
        depth(&mut a, 100 * MS, 1);
        assert!(!a.next_frame(&mut frame));
        assert_eq!(a.counts().before_camera_info, 1);
    }
}
