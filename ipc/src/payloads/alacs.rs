//! Hardware-layer messages of the ALACS unit (laser on a linear slide + RGB camera): the driver
//! commands slide and laser and triggers a capture; the device answers with the image.

use crate::camera_model::CameraIntrinsics;
use crate::codec::{self, CodecError};
use crate::header::Header;
use crate::payload::CustomCodec;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Width of the ALACS camera image, pixels.
pub const ALACS_WIDTH_PX: usize = 1440;
/// Height of the ALACS camera image, pixels.
pub const ALACS_HEIGHT_PX: usize = 1080;
/// Bytes of one ALACS RGB8 image.
pub const ALACS_RGB_BYTES: usize = ALACS_WIDTH_PX * ALACS_HEIGHT_PX * 3;

/// Driver -> device: move the slide, switch the laser, and capture one image once there.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.AlacsCommand.v1")]
pub struct AlacsCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// Chosen by the driver; the device echoes it in its [`AlacsImage`].
    pub request_seq: u32,
    /// 1 laser on.
    pub laser_on: u8,
    /// 1 capture an image after the move.
    pub capture: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// Slide position target, metres from the home end, within the 0.20 m stroke.
    pub slide_target_m: f64,
}

/// How the device carried out a command (code in [`AlacsImage::status`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum AlacsStatus {
    /// Done as asked.
    Ok = 0,
    /// The slide target is outside the stroke: nothing moved.
    SlideOutOfStroke = 1,
    /// The device reports a fault.
    DeviceFault = 2,
}

/// Device -> driver: the answer to one command, with the image when one was requested.
#[repr(C)]
#[derive(ZeroCopySend, crate::AnyBitPattern, crate::Payload)]
#[type_name("harvest.AlacsImage.v1")]
#[payload(custom_codec)]
pub struct AlacsImage {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The `request_seq` of the command answered.
    pub request_seq: u32,
    /// 1 when the laser was on for the capture.
    pub laser_on: u8,
    /// How the device carried out the command.
    pub status: WireCode<AlacsStatus>,
    /// 1 when `rgb` holds a captured image.
    pub has_image: u8,
    /// Zero; keeps the following fields aligned. Not encoded.
    #[schema(skip)]
    pub _reserved: u8,
    /// Where the slide actually stopped, metres.
    pub slide_position_m: f64,
    /// Intrinsics of the ALACS camera the image was taken with.
    pub intrinsics: CameraIntrinsics,
    /// Row-major RGB8, `ALACS_WIDTH_PX` x `ALACS_HEIGHT_PX`.
    pub rgb: [u8; ALACS_RGB_BYTES],
}

impl std::fmt::Debug for AlacsImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AlacsImage")
            .field("header", &self.header)
            .field("request_seq", &self.request_seq)
            .field("status", &self.status)
            .field("slide_position_m", &self.slide_position_m)
            .finish_non_exhaustive()
    }
}

#[derive(Serialize, Deserialize)]
struct AlacsImageMeta {
    header: Header,
    request_seq: u32,
    laser_on: u8,
    status: WireCode<AlacsStatus>,
    has_image: u8,
    slide_position_m: f64,
    intrinsics: CameraIntrinsics,
}

impl CustomCodec for AlacsImage {
    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        let meta = AlacsImageMeta {
            header: self.header,
            request_seq: self.request_seq,
            laser_on: self.laser_on,
            status: self.status,
            has_image: self.has_image,
            slide_position_m: self.slide_position_m,
            intrinsics: self.intrinsics,
        };
        codec::encode_into(&meta, out)?;
        out.extend_from_slice(&self.rgb);
        Ok(())
    }
    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError> {
        let (meta, used): (AlacsImageMeta, usize) = codec::decode_prefix(bytes)?;
        let expected = used + ALACS_RGB_BYTES;
        if bytes.len() != expected {
            return Err(CodecError::Length {
                expected,
                actual: bytes.len(),
            });
        }
        dst.header = meta.header;
        dst.request_seq = meta.request_seq;
        dst.laser_on = meta.laser_on;
        dst.status = meta.status;
        dst.has_image = meta.has_image;
        dst._reserved = 0;
        dst.slide_position_m = meta.slide_position_m;
        dst.intrinsics = meta.intrinsics;
        dst.rgb.copy_from_slice(&bytes[used..]);
        Ok(())
    }
    fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "header": self.header,
            "request_seq": self.request_seq,
            "laser_on": self.laser_on,
            "status": self.status,
            "has_image": self.has_image,
            "slide_position_m": self.slide_position_m,
            "intrinsics": self.intrinsics,
            "rgb_bytes": ALACS_RGB_BYTES,
        })
    }
}
