//! H.264 encoding and decoding of the camera's colour images for the continuous record, with
//! Cisco's OpenH264 (the `openh264` crate compiling its bundled source; BSD-2-Clause).
//!
//! What the encoder produces is what `foxglove.CompressedVideo` asks for: Annex B, one access
//! unit per frame, Constrained Baseline (OpenH264 encodes no B slices), an IDR with SPS and PPS
//! at least every `keyframe_interval` frames (forced by the frame count, so the spacing holds
//! whatever the encoder's scene detection does). Frames are never skipped by the rate control:
//! every frame given becomes one access unit. The encoder runs on the calling thread only
//! (one core), so its cost is the caller's to place.

use openh264::OpenH264API;
use openh264::decoder::Decoder;
use openh264::encoder::{
    BitRate, Complexity, Encoder, EncoderConfig, FrameRate, FrameType, IntraFramePeriod,
    RateControlMode, SpsPpsStrategy, UsageType,
};
use openh264::formats::{RgbSliceU8, YUVBuffer, YUVSource};

/// How the camera video is encoded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VideoSettings {
    /// Frames per second given to the encoder (its rate control's time base).
    pub frame_rate_hz: f64,
    /// Target bit rate, bits per second.
    pub bitrate_bps: u32,
    /// An IDR (with SPS and PPS) at least every this many frames.
    pub keyframe_interval: u32,
}

impl VideoSettings {
    /// 10 frames/s at 2 Mbit/s, an IDR every second.
    pub const DEFAULT: Self = Self {
        frame_rate_hz: 10.0,
        bitrate_bps: 2_000_000,
        keyframe_interval: 10,
    };

    /// Settings at `frame_rate_hz` with an IDR every second (at least one frame apart).
    pub fn at_rate(frame_rate_hz: f64, bitrate_bps: u32) -> Self {
        Self {
            frame_rate_hz,
            bitrate_bps,
            keyframe_interval: (frame_rate_hz.floor() as u32).max(1),
        }
    }
}

impl Default for VideoSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Encoding or decoding failed.
#[derive(Debug, thiserror::Error)]
pub enum VideoError {
    /// The image buffer does not match its dimensions (RGB8: width x height x 3 bytes, both even).
    #[error("image of {width}x{height} needs {expected} RGB8 bytes with even sides, got {actual}")]
    BadImage {
        width: usize,
        height: usize,
        expected: usize,
        actual: usize,
    },
    /// OpenH264 reported an error.
    #[error("OpenH264: {0}")]
    Codec(String),
    /// A decoded picture's size is not the expected one.
    #[error(
        "decoded picture is {width}x{height}, the frame holds {expected_width}x{expected_height}"
    )]
    SizeMismatch {
        width: usize,
        height: usize,
        expected_width: usize,
        expected_height: usize,
    },
}

/// One encoded frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncodedFrame {
    /// True for an IDR (a decoder can start here).
    pub keyframe: bool,
    /// Bytes of the access unit.
    pub size_bytes: usize,
}

/// RGB8 frames -> H.264 access units.
pub struct H264Encoder {
    settings: VideoSettings,
    encoder: Encoder,
    yuv: Option<YUVBuffer>,
    frames_since_keyframe: Option<u32>,
}

impl H264Encoder {
    pub fn new(settings: VideoSettings) -> Result<Self, VideoError> {
        let config = EncoderConfig::new()
            .usage_type(UsageType::CameraVideoRealTime)
            .rate_control_mode(RateControlMode::Bitrate)
            .bitrate(BitRate::from_bps(settings.bitrate_bps))
            .max_frame_rate(FrameRate::from_hz(settings.frame_rate_hz as f32))
            .skip_frames(false)
            .intra_frame_period(IntraFramePeriod::from_num_frames(
                settings.keyframe_interval.max(1),
            ))
            .sps_pps_strategy(SpsPpsStrategy::ConstantId)
            .complexity(Complexity::Low)
            .num_threads(1);
        let encoder = Encoder::with_api_config(OpenH264API::from_source(), config)
            .map_err(|error| VideoError::Codec(error.to_string()))?;
        Ok(Self {
            settings,
            encoder,
            yuv: None,
            frames_since_keyframe: None,
        })
    }

    pub fn settings(&self) -> VideoSettings {
        self.settings
    }

    /// Encodes one RGB8 image (row-major, `width` x `height`) into `out` (cleared first) as one
    /// Annex B access unit.
    pub fn encode_rgb8(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
        out: &mut Vec<u8>,
    ) -> Result<EncodedFrame, VideoError> {
        let expected = width * height * 3;
        if rgb.len() != expected
            || !width.is_multiple_of(2)
            || !height.is_multiple_of(2)
            || width == 0
        {
            return Err(VideoError::BadImage {
                width,
                height,
                expected,
                actual: rgb.len(),
            });
        }
        let yuv = match &mut self.yuv {
            Some(yuv) if yuv.dimensions() == (width, height) => yuv,
            slot => {
                self.frames_since_keyframe = None;
                slot.insert(YUVBuffer::new(width, height))
            }
        };
        yuv.read_rgb8(RgbSliceU8::new(rgb, (width, height)));
        let interval = self.settings.keyframe_interval.max(1);
        if self
            .frames_since_keyframe
            .is_none_or(|frames| frames + 1 >= interval)
        {
            self.encoder.force_intra_frame();
        }
        let stream = self
            .encoder
            .encode(&*yuv)
            .map_err(|error| VideoError::Codec(error.to_string()))?;
        out.clear();
        stream.write_vec(out);
        let keyframe = matches!(stream.frame_type(), FrameType::IDR);
        self.frames_since_keyframe = Some(match (keyframe, self.frames_since_keyframe) {
            (true, _) | (false, None) => 0,
            (false, Some(frames)) => frames + 1,
        });
        Ok(EncodedFrame {
            keyframe,
            size_bytes: out.len(),
        })
    }
}

/// H.264 access units -> RGB8 images.
pub struct H264Decoder {
    decoder: Decoder,
}

impl H264Decoder {
    pub fn new() -> Result<Self, VideoError> {
        let decoder = Decoder::new().map_err(|error| VideoError::Codec(error.to_string()))?;
        Ok(Self { decoder })
    }

    /// Decodes one access unit into `rgb` (RGB8, `width` x `height`). `Ok(false)`: no picture
    /// yet (a stream entered before its first IDR, or a unit that completes none).
    pub fn decode_rgb8(
        &mut self,
        access_unit: &[u8],
        rgb: &mut [u8],
        width: usize,
        height: usize,
    ) -> Result<bool, VideoError> {
        let picture = self
            .decoder
            .decode(access_unit)
            .map_err(|error| VideoError::Codec(error.to_string()))?;
        let Some(picture) = picture else {
            return Ok(false);
        };
        let (decoded_width, decoded_height) = picture.dimensions();
        if (decoded_width, decoded_height) != (width, height) || rgb.len() != width * height * 3 {
            return Err(VideoError::SizeMismatch {
                width: decoded_width,
                height: decoded_height,
                expected_width: width,
                expected_height: height,
            });
        }
        picture.write_rgb8(rgb);
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::annexb::FrameNals;

    const WIDTH: usize = 320;
    const HEIGHT: usize = 240;

    /// A moving gradient with a square: content that changes from frame to frame.
    fn image(frame: usize) -> Vec<u8> {
        let mut rgb = vec![0u8; WIDTH * HEIGHT * 3];
        for y in 0..HEIGHT {
            for x in 0..WIDTH {
                let pixel = (y * WIDTH + x) * 3;
                rgb[pixel] = ((x + frame * 4) % 256) as u8;
                rgb[pixel + 1] = ((y * 2) % 256) as u8;
                let inside = (x + 300 - frame * 7 % 300) % 300 < 40 && (100..160).contains(&y);
                rgb[pixel + 2] = if inside { 230 } else { 40 };
            }
        }
        rgb
    }

    #[test]
    fn idr_with_parameter_sets_every_interval_and_no_b_slices() {
        let settings = VideoSettings {
            frame_rate_hz: 10.0,
            bitrate_bps: 500_000,
            keyframe_interval: 5,
        };
        let mut encoder = H264Encoder::new(settings).expect("encoder");
        let mut out = Vec::new();
        let mut keyframes = Vec::new();
        for frame in 0..23 {
            let encoded = encoder
                .encode_rgb8(&image(frame), WIDTH, HEIGHT, &mut out)
                .expect("encode");
            let nals = FrameNals::of(&out).expect("annex b");
            assert!(!nals.has_b_slices(), "frame {frame}");
            assert!(nals.slice_count() > 0, "frame {frame} was skipped");
            assert_eq!(encoded.keyframe, nals.is_idr(), "frame {frame}");
            if nals.is_idr() {
                assert!(nals.idr_has_parameter_sets(), "frame {frame}");
                keyframes.push(frame);
            }
        }
        assert_eq!(keyframes, vec![0, 5, 10, 15, 20]);
    }

    #[test]
    fn decodes_what_it_encoded() {
        let mut encoder = H264Encoder::new(VideoSettings {
            frame_rate_hz: 10.0,
            bitrate_bps: 4_000_000,
            keyframe_interval: 10,
        })
        .expect("encoder");
        let mut decoder = H264Decoder::new().expect("decoder");
        let mut out = Vec::new();
        let mut decoded = vec![0u8; WIDTH * HEIGHT * 3];
        for frame in 0..6 {
            let source = image(frame);
            encoder
                .encode_rgb8(&source, WIDTH, HEIGHT, &mut out)
                .expect("encode");
            assert!(
                decoder
                    .decode_rgb8(&out, &mut decoded, WIDTH, HEIGHT)
                    .expect("decode")
            );
            let mean_error = source
                .iter()
                .zip(&decoded)
                .map(|(a, b)| f64::from(a.abs_diff(*b)))
                .sum::<f64>()
                / source.len() as f64;
            assert!(mean_error < 8.0, "frame {frame}: mean error {mean_error}");
        }
        assert!(
            encoder
                .encode_rgb8(&[0; 10], WIDTH, HEIGHT, &mut out)
                .is_err()
        );
    }
}
