//! One registered RGB-D frame of the ToF camera (Percipio TL460-S1-E1): colour 1920x1080 RGB8
//! and depth 640x480 in millimetres, with both cameras' intrinsics and the depth-to-colour
//! registration. About 6.8 MB: always loaned and written in place.

use crate::camera_model::{CameraIntrinsics, RigidTransform};
use crate::codec::{self, CodecError};
use crate::header::Header;
use crate::payload::CustomCodec;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Width of the colour image, pixels.
pub const RGB_WIDTH_PX: usize = 1920;
/// Height of the colour image, pixels.
pub const RGB_HEIGHT_PX: usize = 1080;
/// Bytes of one RGB8 colour image.
pub const RGB_BYTES: usize = RGB_WIDTH_PX * RGB_HEIGHT_PX * 3;
/// Width of the depth image, pixels.
pub const DEPTH_WIDTH_PX: usize = 640;
/// Height of the depth image, pixels.
pub const DEPTH_HEIGHT_PX: usize = 480;
/// Pixels of one depth image.
pub const DEPTH_PIXELS: usize = DEPTH_WIDTH_PX * DEPTH_HEIGHT_PX;

/// Frame metadata: everything but the pixel buffers.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Describe,
)]
pub struct RgbdFrameMeta {
    /// Intrinsics of the colour camera.
    pub rgb_intrinsics: CameraIntrinsics,
    /// Intrinsics of the depth camera.
    pub depth_intrinsics: CameraIntrinsics,
    /// Registration: maps points in the depth camera frame to the colour camera frame.
    pub color_from_depth: RigidTransform,
    /// Exposure time of the colour image, microseconds.
    pub exposure_us: u32,
    /// Bit 0: the driver saw saturated (over-exposed) regions. Bit 1: the frame is colour only
    /// ([`Self::FLAG_COLOR_ONLY`]).
    pub flags: u32,
}

impl RgbdFrameMeta {
    /// Bit of [`Self::flags`]: saturated regions were seen.
    pub const FLAG_OVER_EXPOSED: u32 = 1;
    /// Bit of [`Self::flags`]: the frame is colour only (a camera without a depth sensor, e.g. a
    /// GigE Vision camera). `depth_mm` holds no measurement (all 0, which must not be read as
    /// "no return"); `depth_intrinsics` is the grid on which a depth image from another sensor
    /// (the LiDAR) is laid, and `color_from_depth` maps that grid's frame to the colour camera's.
    pub const FLAG_COLOR_ONLY: u32 = 2;

    /// Whether the frame carries no depth measurement of its own ([`Self::FLAG_COLOR_ONLY`]).
    pub fn is_color_only(&self) -> bool {
        self.flags & Self::FLAG_COLOR_ONLY != 0
    }
}

impl Default for RgbdFrameMeta {
    fn default() -> Self {
        Self {
            rgb_intrinsics: CameraIntrinsics::tl460_rgb(),
            depth_intrinsics: CameraIntrinsics::tl460_depth(),
            color_from_depth: RigidTransform::IDENTITY,
            exposure_us: 0,
            flags: 0,
        }
    }
}

/// One registered RGB-D frame of the ToF camera (`camera/rgbd`, `hw/camera/rgbd`).
#[repr(C)]
#[derive(ZeroCopySend, crate::AnyBitPattern, crate::Payload)]
#[type_name("harvest.RgbdFrame.v1")]
#[payload(custom_codec)]
pub struct RgbdFrame {
    /// `capture_ns` is the exposure time of the frame; see [`Header`].
    pub header: Header,
    /// Intrinsics, registration, exposure and flags.
    pub meta: RgbdFrameMeta,
    /// Row-major RGB8, `RGB_WIDTH_PX` x `RGB_HEIGHT_PX`.
    pub rgb: [u8; RGB_BYTES],
    /// Row-major depth in millimetres, 0 = no return, `DEPTH_WIDTH_PX` x `DEPTH_HEIGHT_PX`.
    pub depth_mm: [u16; DEPTH_PIXELS],
}

impl std::fmt::Debug for RgbdFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RgbdFrame")
            .field("header", &self.header)
            .field("meta", &self.meta)
            .finish_non_exhaustive()
    }
}

impl CustomCodec for RgbdFrame {
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        out.reserve(RGB_BYTES + DEPTH_PIXELS * 2 + 512);
        codec::encode_into(&(self.header, self.meta), out)?;
        out.extend_from_slice(&self.rgb);
        out.extend(self.depth_mm.iter().flat_map(|depth| depth.to_le_bytes()));
        Ok(())
    }

    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError> {
        let ((header, meta), used): ((Header, RgbdFrameMeta), usize) = codec::decode_prefix(bytes)?;
        let expected = used + RGB_BYTES + DEPTH_PIXELS * 2;
        if bytes.len() != expected {
            return Err(CodecError::Length {
                expected,
                actual: bytes.len(),
            });
        }
        dst.header = header;
        dst.meta = meta;
        dst.rgb.copy_from_slice(&bytes[used..used + RGB_BYTES]);
        for (depth, pair) in dst
            .depth_mm
            .iter_mut()
            .zip(bytes[used + RGB_BYTES..].chunks_exact(2))
        {
            *depth = u16::from_le_bytes([pair[0], pair[1]]);
        }
        Ok(())
    }

    fn to_json(&self) -> serde_json::Value {
        let valid_depth = self.depth_mm.iter().filter(|&&d| d != 0).count();
        serde_json::json!({
            "header": self.header,
            "meta": self.meta,
            "rgb_bytes": RGB_BYTES,
            "depth_pixels": DEPTH_PIXELS,
            "depth_valid_pixels": valid_depth,
        })
    }
}

impl RgbdFrame {
    /// Depth at a depth pixel, `None` for no return or out of range.
    pub fn depth_at_mm(&self, u_px: usize, v_px: usize) -> Option<u16> {
        if u_px >= DEPTH_WIDTH_PX || v_px >= DEPTH_HEIGHT_PX {
            return None;
        }
        match self.depth_mm[v_px * DEPTH_WIDTH_PX + u_px] {
            0 => None,
            depth => Some(depth),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed_frame() -> Box<RgbdFrame> {
        crate::payload::boxed_zeroed()
    }

    #[test]
    fn encode_decode_round_trip() {
        let mut frame = boxed_frame();
        frame.header.msg_seq = 42;
        frame.meta = RgbdFrameMeta::default();
        frame.rgb[7] = 200;
        frame.depth_mm[DEPTH_PIXELS - 1] = 1234;
        let mut bytes = Vec::new();
        frame.encode(&mut bytes).expect("encode");
        let mut back = boxed_frame();
        RgbdFrame::decode_into(&bytes, &mut back).expect("decode");
        assert_eq!(back.header.msg_seq, 42);
        assert_eq!(back.meta, frame.meta);
        assert_eq!(back.rgb[7], 200);
        assert_eq!(
            back.depth_at_mm(DEPTH_WIDTH_PX - 1, DEPTH_HEIGHT_PX - 1),
            Some(1234)
        );
        assert!(RgbdFrame::decode_into(&bytes[..bytes.len() - 1], &mut back).is_err());
    }
}
