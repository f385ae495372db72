//! The camera on the link: the colour image downscaled by an integer factor (the same box
//! filter as the console and the Foxglove view, `harvest_perception::downscale`) and encoded as
//! JPEG. The frame's sequence, capture stamp and size travel beside the JPEG as a small JSON
//! attachment, so a station measures the image's age and notices gaps without decoding it.

use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};
use harvest_perception::downscale::downscale_rgb;
use serde::{Deserialize, Serialize};

/// How the image is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraImageSettings {
    /// Camera pixels per image pixel (4: 480x270 from 1920x1080).
    pub scale: u32,
    /// JPEG quality 1-100.
    pub jpeg_quality: u8,
    /// Images a second at most (<= 2).
    pub max_hz: f64,
}

impl Default for CameraImageSettings {
    /// 480x270 at quality 70 (about 15-30 kB), 2 Hz: well under 2 MB/s per robot.
    fn default() -> Self {
        Self {
            scale: 4,
            jpeg_quality: 70,
            max_hz: 2.0,
        }
    }
}

impl CameraImageSettings {
    /// The problem with these settings, if any.
    pub fn problem(&self) -> Option<String> {
        if !(1..=16).contains(&self.scale) {
            return Some(format!("camera scale {} is not in 1..=16", self.scale));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return Some(format!(
                "JPEG quality {} is not in 1..=100",
                self.jpeg_quality
            ));
        }
        if !(self.max_hz > 0.0 && self.max_hz <= 2.0) {
            return Some(format!("camera rate {} Hz is not in (0, 2]", self.max_hz));
        }
        None
    }

    /// Width and height of the image, px.
    pub fn size_px(&self) -> (usize, usize) {
        let scale = self.scale.max(1) as usize;
        (RGB_WIDTH_PX / scale, RGB_HEIGHT_PX / scale)
    }
}

/// What travels beside the JPEG.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct CameraAttachment {
    /// The frame's `msg_seq` on `camera/rgbd`.
    pub frame_seq: u64,
    /// The frame's capture time, ns on the robot's monotonic clock.
    pub capture_ns: u64,
    pub width_px: u32,
    pub height_px: u32,
}

impl CameraAttachment {
    pub fn to_json(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }
}

/// Reusable buffers of the encoder.
#[derive(Debug, Default)]
pub struct CameraEncoder {
    small: Vec<u8>,
    jpeg: Vec<u8>,
}

impl CameraEncoder {
    /// The JPEG of `frame` (borrowed until the next call) and its attachment.
    pub fn encode(
        &mut self,
        frame: &RgbdFrame,
        settings: &CameraImageSettings,
    ) -> Result<(&[u8], CameraAttachment), image::ImageError> {
        let (width, height) = settings.size_px();
        downscale_rgb(
            &frame.rgb,
            RGB_WIDTH_PX,
            settings.scale.max(1) as usize,
            (width, height),
            &mut self.small,
        );
        self.jpeg.clear();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut self.jpeg, settings.jpeg_quality)
            .encode(
            &self.small,
            width as u32,
            height as u32,
            image::ExtendedColorType::Rgb8,
        )?;
        Ok((
            &self.jpeg,
            CameraAttachment {
                frame_seq: frame.header.msg_seq,
                capture_ns: frame.header.capture_ns,
                width_px: width as u32,
                height_px: height as u32,
            },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_becomes_a_small_jpeg() {
        let mut frame: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        for (i, px) in frame.rgb.chunks_exact_mut(3).enumerate() {
            px[0] = (i % 251) as u8;
            px[1] = 120;
        }
        frame.header.msg_seq = 9;
        frame.header.capture_ns = 77;
        let settings = CameraImageSettings::default();
        assert_eq!(settings.problem(), None);
        let mut encoder = CameraEncoder::default();
        let (jpeg, attachment) = encoder.encode(&frame, &settings).expect("jpeg");
        assert_eq!(&jpeg[..2], &[0xff, 0xd8]);
        assert!(jpeg.len() < 200_000, "{} bytes", jpeg.len());
        assert_eq!(attachment.frame_seq, 9);
        assert_eq!((attachment.width_px, attachment.height_px), (480, 270));
        assert!(
            CameraImageSettings {
                max_hz: 5.0,
                ..settings
            }
            .problem()
            .is_some()
        );
    }
}
