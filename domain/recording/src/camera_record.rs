//! The camera in the continuous record: instead of raw `camera/rgbd` frames (6.8 MB each), the
//! colour images as H.264 video and the depth images at a reduced rate, losslessly compressed.
//!
//! - `camera/video`: `foxglove.CompressedVideo` (protobuf), `format` `h264`, one access unit per
//!   message (see [`crate::video_codec`]); `timestamp` is the frame's `capture_ns` on the file's
//!   wall-clock time base (`capture_ns + log_time_offset_ns`), `frame_id` the colour camera's.
//!   Foxglove shows it as it is.
//! - `camera/depth`: `harvest.RgbdDepth.v1`, the frame's header and metadata (intrinsics,
//!   registration, exposure: bincode, like every raw channel) followed by the depth image as a
//!   16-bit greyscale PNG (lossless). A depth message is written with the video frame of the
//!   same capture, before it, so every depth image has its colour image.
//!
//! `harvest replay` puts the two back together into `camera/rgbd` frames ([`CameraRebuild`]).

use crate::segment_writer::ForeignChannel;
use crate::video_codec::{H264Decoder, VideoError};
use foxglove::messages::{CompressedVideo, Timestamp};
use foxglove::{Decode, Encode};
use harvest_ipc::codec::{self, CodecError};
use harvest_ipc::header::Header;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_PIXELS, DEPTH_WIDTH_PX, RGB_BYTES, RGB_HEIGHT_PX, RGB_WIDTH_PX,
    RgbdFrameMeta,
};
use image::ImageEncoder;
use image::codecs::png::{CompressionType, FilterType, PngDecoder, PngEncoder};
use std::collections::BTreeMap;

/// The colour images as H.264.
pub const VIDEO_TOPIC: &str = "camera/video";
/// The depth images with the frames' metadata.
pub const DEPTH_TOPIC: &str = "camera/depth";
/// Schema of [`DEPTH_TOPIC`].
pub const DEPTH_SCHEMA: &str = "harvest.RgbdDepth.v1";
/// Message encoding of [`DEPTH_TOPIC`].
pub const DEPTH_ENCODING: &str = "bincode2-fixint-le+png16";
/// `frame_id` of the video (the colour camera's optical frame, as in the mapped channels).
pub const VIDEO_FRAME_ID: &str = "camera_color";

/// The video channel as the recording registers it.
pub fn video_channel() -> ForeignChannel {
    let schema = CompressedVideo::get_schema();
    ForeignChannel {
        topic: VIDEO_TOPIC.to_owned(),
        schema_name: schema
            .as_ref()
            .map_or_else(String::new, |schema| schema.name.clone()),
        schema_encoding: schema
            .as_ref()
            .map_or_else(String::new, |schema| schema.encoding.clone()),
        schema_data: schema.map_or_else(Vec::new, |schema| schema.data.to_vec()),
        message_encoding: CompressedVideo::get_message_encoding(),
        metadata: BTreeMap::from([
            (
                "description".to_owned(),
                "camera/rgbd colour images as H.264 (Annex B, an IDR with SPS/PPS every second, no B-frames)".to_owned(),
            ),
            ("source".to_owned(), "camera/rgbd".to_owned()),
        ]),
    }
}

/// The depth channel as the recording registers it.
pub fn depth_channel() -> ForeignChannel {
    ForeignChannel {
        topic: DEPTH_TOPIC.to_owned(),
        schema_name: DEPTH_SCHEMA.to_owned(),
        schema_encoding: DEPTH_ENCODING.to_owned(),
        schema_data: format!(
            "harvest message schema\ntype: harvest.RgbdDepth\nversion: 1\nencoding: {DEPTH_ENCODING}\n\
layout: (header: Header{{msg_seq:u64, capture_ns:u64, publish_ns:u64}}, meta: RgbdFrameMeta) in \
bincode2-fixint-le as in harvest.RgbdFrame.v1, then depth_mm as a 16-bit greyscale PNG \
({DEPTH_WIDTH_PX}x{DEPTH_HEIGHT_PX}, millimetres, 0 = no return)\n"
        )
        .into_bytes(),
        message_encoding: DEPTH_ENCODING.to_owned(),
        metadata: BTreeMap::from([
            (
                "description".to_owned(),
                "camera/rgbd depth images at a reduced rate, lossless (PNG), with the frame's metadata".to_owned(),
            ),
            ("source".to_owned(), "camera/rgbd".to_owned()),
        ]),
    }
}

/// A camera message of the continuous record that cannot be made or read.
#[derive(Debug, thiserror::Error)]
pub enum CameraRecordError {
    #[error("frame header and metadata: {0}")]
    Codec(#[from] CodecError),
    #[error("depth PNG: {0}")]
    Png(String),
    #[error("CompressedVideo protobuf: {0}")]
    Protobuf(String),
    #[error("video format {0:?} (only h264 is read)")]
    Format(String),
    #[error(transparent)]
    Video(#[from] VideoError),
}

/// A `camera/video` message: one access unit captured at `capture_wall_ns` (Unix-epoch ns).
pub fn encode_video_message(capture_wall_ns: u64, access_unit: &[u8], out: &mut Vec<u8>) {
    let message = CompressedVideo {
        timestamp: Some(timestamp_of_ns(capture_wall_ns)),
        frame_id: VIDEO_FRAME_ID.to_owned(),
        data: foxglove::bytes::Bytes::copy_from_slice(access_unit),
        format: "h264".to_owned(),
    };
    out.clear();
    out.reserve(message.encoded_len().unwrap_or(access_unit.len() + 64));
    // Encoding into a Vec only fails for lack of capacity, which a Vec grows.
    let _ = Encode::encode(&message, out);
}

/// A decoded `camera/video` message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VideoMessage {
    /// `timestamp`, Unix-epoch ns.
    pub capture_wall_ns: u64,
    pub access_unit: Vec<u8>,
}

pub fn decode_video_message(bytes: &[u8]) -> Result<VideoMessage, CameraRecordError> {
    let message = <CompressedVideo as Decode>::decode(bytes)
        .map_err(|error| CameraRecordError::Protobuf(error.to_string()))?;
    if message.format != "h264" {
        return Err(CameraRecordError::Format(message.format));
    }
    let capture_wall_ns = message.timestamp.map_or(0, |stamp| {
        u64::from(stamp.sec()) * 1_000_000_000 + u64::from(stamp.nsec())
    });
    Ok(VideoMessage {
        capture_wall_ns,
        access_unit: message.data.to_vec(),
    })
}

fn timestamp_of_ns(ns: u64) -> Timestamp {
    let sec = u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new_checked(sec, (ns % 1_000_000_000) as u32).unwrap_or(Timestamp::MAX)
}

/// A `camera/rgbd` message as the raw channel encodes it, split into its parts (no copy).
#[derive(Debug, Clone, Copy)]
pub struct EncodedFrameParts<'a> {
    pub header: Header,
    pub meta: RgbdFrameMeta,
    /// RGB8, row-major.
    pub rgb: &'a [u8],
    /// Depth in millimetres, u16 little-endian, row-major.
    pub depth_le: &'a [u8],
}

/// Splits an encoded `camera/rgbd` message (`RgbdFrame::encode`'s layout).
pub fn split_encoded_frame(bytes: &[u8]) -> Result<EncodedFrameParts<'_>, CameraRecordError> {
    let ((header, meta), used): ((Header, RgbdFrameMeta), usize) = codec::decode_prefix(bytes)?;
    let expected = used + RGB_BYTES + DEPTH_PIXELS * 2;
    if bytes.len() != expected {
        return Err(CodecError::Length {
            expected,
            actual: bytes.len(),
        }
        .into());
    }
    let (rgb, depth_le) = bytes[used..].split_at(RGB_BYTES);
    Ok(EncodedFrameParts {
        header,
        meta,
        rgb,
        depth_le,
    })
}

/// A `camera/depth` message of a frame (its header, metadata and depth image).
pub fn encode_depth_message(
    parts: &EncodedFrameParts<'_>,
    out: &mut Vec<u8>,
) -> Result<(), CameraRecordError> {
    out.clear();
    codec::encode_into(&(parts.header, parts.meta), out)?;
    let mut native = Vec::with_capacity(DEPTH_PIXELS * 2);
    native.extend(
        parts
            .depth_le
            .chunks_exact(2)
            .flat_map(|pair| u16::from_le_bytes([pair[0], pair[1]]).to_ne_bytes()),
    );
    PngEncoder::new_with_quality(&mut *out, CompressionType::Fast, FilterType::Up)
        .write_image(
            &native,
            DEPTH_WIDTH_PX as u32,
            DEPTH_HEIGHT_PX as u32,
            image::ExtendedColorType::L16,
        )
        .map_err(|error| CameraRecordError::Png(error.to_string()))
}

/// Reads a `camera/depth` message: its header and metadata, the depth image into `depth_mm`.
pub fn decode_depth_message(
    bytes: &[u8],
    depth_mm: &mut [u16],
) -> Result<(Header, RgbdFrameMeta), CameraRecordError> {
    let ((header, meta), used): ((Header, RgbdFrameMeta), usize) = codec::decode_prefix(bytes)?;
    let png = bytes.get(used..).unwrap_or_default();
    let decoder = PngDecoder::new(std::io::Cursor::new(png))
        .map_err(|error| CameraRecordError::Png(error.to_string()))?;
    let (width, height) = image::ImageDecoder::dimensions(&decoder);
    let color = image::ImageDecoder::color_type(&decoder);
    if (width as usize, height as usize) != (DEPTH_WIDTH_PX, DEPTH_HEIGHT_PX)
        || color != image::ColorType::L16
        || depth_mm.len() != DEPTH_PIXELS
    {
        return Err(CameraRecordError::Png(format!(
            "{width}x{height} {color:?}, expected {DEPTH_WIDTH_PX}x{DEPTH_HEIGHT_PX} L16"
        )));
    }
    let mut native = vec![0u8; DEPTH_PIXELS * 2];
    image::ImageDecoder::read_image(decoder, &mut native)
        .map_err(|error| CameraRecordError::Png(error.to_string()))?;
    for (depth, pair) in depth_mm.iter_mut().zip(native.chunks_exact(2)) {
        *depth = u16::from_ne_bytes([pair[0], pair[1]]);
    }
    Ok((header, meta))
}

/// A JSON view of a message of the camera's channels (`rec cat`): a video frame's timestamp,
/// size and NAL unit types; a depth image's header, metadata and PNG size. `None` for another
/// topic or a message that does not decode.
pub fn camera_json(topic: &str, bytes: &[u8]) -> Option<serde_json::Value> {
    match topic {
        VIDEO_TOPIC => {
            let video = decode_video_message(bytes).ok()?;
            let nals = crate::annexb::FrameNals::of(&video.access_unit).ok();
            Some(serde_json::json!({
                "timestamp_ns": video.capture_wall_ns,
                "format": "h264",
                "bytes": video.access_unit.len(),
                "idr": nals.as_ref().is_some_and(|nals| nals.is_idr()),
                "nal_unit_types": nals.map(|nals| nals.unit_types).unwrap_or_default(),
            }))
        }
        DEPTH_TOPIC => {
            let ((header, meta), used): ((Header, RgbdFrameMeta), usize) =
                codec::decode_prefix(bytes).ok()?;
            Some(serde_json::json!({
                "header": header,
                "meta": meta,
                "png_bytes": bytes.len().saturating_sub(used),
            }))
        }
        _ => None,
    }
}

/// Puts `camera/rgbd` frames back together from the continuous record's video and depth.
///
/// Each video frame becomes one frame: its colour image decoded, its `capture_ns` from the
/// video's timestamp (back on the stack clock), and the depth, metadata and `msg_seq` of the
/// newest depth message captured at or before it (the one of the same capture when the
/// recorder kept that frame's depth). Video frames before the first depth message or before
/// the first IDR give no frame (counted by the caller from [`Rebuilt`]).
pub struct CameraRebuild {
    decoder: H264Decoder,
    depth: Option<(Header, RgbdFrameMeta, Box<[u16]>)>,
}

/// What [`CameraRebuild::video`] did with one video message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rebuilt {
    /// The frame was written.
    Frame,
    /// No depth message was seen yet.
    NoDepthYet,
    /// The decoder has no picture yet (entered the stream before an IDR).
    NoPictureYet,
}

impl CameraRebuild {
    pub fn new() -> Result<Self, CameraRecordError> {
        Ok(Self {
            decoder: H264Decoder::new()?,
            depth: None,
        })
    }

    /// Takes in a `camera/depth` message.
    pub fn depth(&mut self, bytes: &[u8]) -> Result<(), CameraRecordError> {
        let mut depth_mm = match self.depth.take() {
            Some((_, _, buffer)) => buffer,
            None => vec![0u16; DEPTH_PIXELS].into_boxed_slice(),
        };
        let result = decode_depth_message(bytes, &mut depth_mm);
        match result {
            Ok((header, meta)) => {
                self.depth = Some((header, meta, depth_mm));
                Ok(())
            }
            Err(error) => Err(error),
        }
    }

    /// Decodes a `camera/video` message into `frame` (every field written when it returns
    /// [`Rebuilt::Frame`]); `stack_ns` maps the video's wall-clock timestamp back to the stack
    /// clock.
    pub fn video(
        &mut self,
        bytes: &[u8],
        stack_ns: impl Fn(u64) -> u64,
        frame: &mut RgbdFrame,
    ) -> Result<Rebuilt, CameraRecordError> {
        let message = decode_video_message(bytes)?;
        // Decode even without depth, so the decoder keeps its references.
        let pictured = self.decoder.decode_rgb8(
            &message.access_unit,
            &mut frame.rgb,
            RGB_WIDTH_PX,
            RGB_HEIGHT_PX,
        )?;
        if !pictured {
            return Ok(Rebuilt::NoPictureYet);
        }
        let Some((header, meta, depth_mm)) = &self.depth else {
            return Ok(Rebuilt::NoDepthYet);
        };
        let capture_ns = stack_ns(message.capture_wall_ns);
        frame.header = Header {
            msg_seq: header.msg_seq,
            capture_ns,
            publish_ns: header.publish_ns.max(capture_ns),
        };
        frame.meta = *meta;
        frame.depth_mm.copy_from_slice(depth_mm);
        Ok(Rebuilt::Frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::video_codec::{H264Encoder, VideoSettings};

    fn frame_with(seed: u16) -> Box<RgbdFrame> {
        let mut frame: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        frame.header = Header {
            msg_seq: 7,
            capture_ns: 1_000_000_000,
            publish_ns: 1_000_500_000,
        };
        frame.meta = RgbdFrameMeta::default();
        frame.meta.exposure_us = 900;
        for (index, depth) in frame.depth_mm.iter_mut().enumerate() {
            *depth = if index % 97 == 0 {
                0
            } else {
                600 + (index % 640) as u16 / 3 + seed
            };
        }
        for (index, byte) in frame.rgb.iter_mut().enumerate() {
            *byte = ((index / 3 % RGB_WIDTH_PX) / 8) as u8;
        }
        frame
    }

    #[test]
    fn depth_is_lossless() {
        let frame = frame_with(3);
        let mut encoded = Vec::new();
        harvest_ipc::Payload::encode(&*frame, &mut encoded).expect("frame");
        let parts = split_encoded_frame(&encoded).expect("split");
        assert_eq!(parts.header, frame.header);
        assert_eq!(parts.rgb, &frame.rgb[..]);
        let mut bytes = Vec::new();
        encode_depth_message(&parts, &mut bytes).expect("encode");
        assert!(bytes.len() < DEPTH_PIXELS * 2 / 2, "{} bytes", bytes.len());
        let mut depth = vec![0u16; DEPTH_PIXELS];
        let (header, meta) = decode_depth_message(&bytes, &mut depth).expect("decode");
        assert_eq!(header, frame.header);
        assert_eq!(meta, frame.meta);
        assert_eq!(&depth[..], &frame.depth_mm[..]);
    }

    #[test]
    fn rebuilds_frames_from_video_and_depth() {
        let offset_ns = 1_700_000_000_000_000_000u64;
        let source = frame_with(0);
        let mut encoder = H264Encoder::new(VideoSettings::DEFAULT).expect("encoder");
        let mut unit = Vec::new();
        encoder
            .encode_rgb8(&source.rgb, RGB_WIDTH_PX, RGB_HEIGHT_PX, &mut unit)
            .expect("encode");
        let mut video = Vec::new();
        encode_video_message(source.header.capture_ns + offset_ns, &unit, &mut video);
        let mut encoded = Vec::new();
        harvest_ipc::Payload::encode(&*source, &mut encoded).expect("frame");
        let mut depth = Vec::new();
        encode_depth_message(&split_encoded_frame(&encoded).expect("split"), &mut depth)
            .expect("depth");

        let mut rebuild = CameraRebuild::new().expect("rebuild");
        let mut frame: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        let back = |wall: u64| wall - offset_ns;
        // Without depth the frame is not complete.
        assert_eq!(
            rebuild.video(&video, back, &mut frame).expect("video"),
            Rebuilt::NoDepthYet
        );
        rebuild.depth(&depth).expect("depth");
        assert_eq!(
            rebuild.video(&video, back, &mut frame).expect("video"),
            Rebuilt::Frame
        );
        assert_eq!(frame.header.capture_ns, source.header.capture_ns);
        assert_eq!(frame.header.msg_seq, source.header.msg_seq);
        assert_eq!(frame.meta, source.meta);
        assert_eq!(&frame.depth_mm[..], &source.depth_mm[..]);
        let mean_error = source
            .rgb
            .iter()
            .zip(frame.rgb.iter())
            .map(|(a, b)| f64::from(a.abs_diff(*b)))
            .sum::<f64>()
            / source.rgb.len() as f64;
        assert!(mean_error < 6.0, "mean colour error {mean_error}");
    }
}
