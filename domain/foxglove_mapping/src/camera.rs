//! `camera/rgbd` -> `/camera/image` (JPEG), `/camera/calibration` and the camera mounting on
//! `/tf`. The image is downscaled by an integer factor (box filter) before encoding; the
//! calibration and the annotations ([`crate::detections`]) are scaled the same way.

use crate::error::MapError;
use crate::frames;
use crate::geometry::frame_transform;
use crate::stamps::TimeBase;
use crate::topics::{self, MappedSink};
use foxglove::bytes::Bytes;
use foxglove::messages::{CameraCalibration, CompressedImage, FrameTransforms};
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};
pub use harvest_perception::downscale::downscale_rgb;

/// Largest accepted downscale factor.
pub const MAX_SCALE: u32 = 8;

/// How the colour image is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSettings {
    /// Integer downscale factor: 1 full size, 2 half width and height (the live default).
    pub scale: u32,
    /// JPEG quality, 1..=100.
    pub jpeg_quality: u8,
}

impl ImageSettings {
    /// The viewing default: half size (960x540), quality 80.
    pub const VIEWING: Self = Self {
        scale: 2,
        jpeg_quality: 80,
    };

    /// The problem with these settings, if any (named for the command line).
    pub fn problem(&self) -> Option<String> {
        if !(1..=MAX_SCALE).contains(&self.scale) {
            return Some(format!(
                "image scale {} is not in 1..={MAX_SCALE}",
                self.scale
            ));
        }
        if !(1..=100).contains(&self.jpeg_quality) {
            return Some(format!(
                "JPEG quality {} is not in 1..=100",
                self.jpeg_quality
            ));
        }
        None
    }

    /// Width and height of the image shown, px.
    pub fn image_size_px(&self) -> (u32, u32) {
        let scale = self.scale.max(1);
        (RGB_WIDTH_PX as u32 / scale, RGB_HEIGHT_PX as u32 / scale)
    }

    /// A colour-image pixel coordinate (continuous, origin at the top-left corner of the
    /// top-left pixel) in the image shown.
    pub fn to_shown_px(&self, coordinate_px: f64) -> f64 {
        coordinate_px / f64::from(self.scale.max(1))
    }

    /// The intrinsics of the image shown: focal lengths and principal point divided by the
    /// scale (pixel-centre convention: `c' = (c + 0.5) / s - 0.5`).
    pub fn scaled_intrinsics(&self, intrinsics: &CameraIntrinsics) -> CameraIntrinsics {
        let scale = f64::from(self.scale.max(1));
        let (width_px, height_px) = self.image_size_px();
        CameraIntrinsics {
            width_px,
            height_px,
            fx_px: intrinsics.fx_px / scale,
            fy_px: intrinsics.fy_px / scale,
            cx_px: (intrinsics.cx_px + 0.5) / scale - 0.5,
            cy_px: (intrinsics.cy_px + 0.5) / scale - 0.5,
            distortion: intrinsics.distortion,
        }
    }
}

/// Encodes colour images, reusing its buffers.
#[derive(Debug)]
pub struct JpegEncoder {
    settings: ImageSettings,
    scaled: Vec<u8>,
}

impl JpegEncoder {
    pub fn new(settings: ImageSettings) -> Self {
        Self {
            settings,
            scaled: Vec::new(),
        }
    }

    pub fn settings(&self) -> ImageSettings {
        self.settings
    }

    /// The frame's colour image, downscaled and JPEG-encoded into a new buffer.
    pub fn encode(&mut self, frame: &RgbdFrame) -> Result<Vec<u8>, image::ImageError> {
        let (width, height) = self.settings.image_size_px();
        let pixels: &[u8] = if self.settings.scale <= 1 {
            &frame.rgb
        } else {
            downscale_rgb(
                &frame.rgb,
                RGB_WIDTH_PX,
                self.settings.scale as usize,
                (width as usize, height as usize),
                &mut self.scaled,
            );
            &self.scaled
        };
        // About 1 bit per pixel at quality 80 on our scenes; the guess only saves regrowing.
        let mut jpeg = Vec::with_capacity(pixels.len() / 8);
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, self.settings.jpeg_quality)
            .encode(pixels, width, height, image::ExtendedColorType::Rgb8)?;
        Ok(jpeg)
    }
}

/// Pinhole intrinsics as a `CameraCalibration` (OpenCV `plumb_bob`: k1, k2, p1, p2, k3).
pub fn calibration(
    intrinsics: &CameraIntrinsics,
    frame_id: &str,
    timestamp: foxglove::messages::Timestamp,
) -> CameraCalibration {
    let k = intrinsics;
    CameraCalibration {
        timestamp: Some(timestamp),
        frame_id: frame_id.to_owned(),
        width: k.width_px,
        height: k.height_px,
        distortion_model: "plumb_bob".to_owned(),
        d: k.distortion.to_vec(),
        k: vec![k.fx_px, 0.0, k.cx_px, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 1.0],
        r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: vec![
            k.fx_px, 0.0, k.cx_px, 0.0, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
    }
}

/// Maps camera frames: the image (encoded by the caller, usually on a thread of its own), its
/// calibration and the camera's transforms.
#[derive(Debug, Clone)]
pub struct CameraMapper {
    settings: ImageSettings,
    time: TimeBase,
    /// The colour sensor's pose in the robot frame (the calibration file); `None`: the camera
    /// frames are not attached to the robot in the 3D view.
    robot_from_camera: Option<RigidTransform>,
}

impl CameraMapper {
    pub fn new(
        settings: ImageSettings,
        time: TimeBase,
        robot_from_camera: Option<RigidTransform>,
    ) -> Self {
        Self {
            settings,
            time,
            robot_from_camera,
        }
    }

    /// Writes `/camera/image` (the JPEG `jpeg` of `frame`), `/camera/calibration` and the
    /// camera's transforms on `/tf`, all stamped with the frame's capture time.
    pub fn write<S: MappedSink>(
        &self,
        frame: &RgbdFrame,
        jpeg: Vec<u8>,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        let timestamp = self.time.timestamp(frame.header.capture_ns);
        let log_time_ns = self.time.ns(log_time_ns);
        let image = CompressedImage {
            timestamp: Some(timestamp),
            frame_id: frames::CAMERA_COLOR.to_owned(),
            data: Bytes::from(jpeg),
            format: "jpeg".to_owned(),
        };
        sink.write(topics::CAMERA_IMAGE, log_time_ns, &image)
            .map_err(MapError::Sink)?;
        let intrinsics = self.settings.scaled_intrinsics(&frame.meta.rgb_intrinsics);
        sink.write(
            topics::CAMERA_CALIBRATION,
            log_time_ns,
            &calibration(&intrinsics, frames::CAMERA_COLOR, timestamp),
        )
        .map_err(MapError::Sink)?;
        let mut transforms = vec![frame_transform(
            timestamp,
            frames::CAMERA_COLOR,
            frames::CAMERA_DEPTH,
            &frame.meta.color_from_depth,
        )];
        if let Some(robot_from_camera) = &self.robot_from_camera {
            transforms.push(frame_transform(
                timestamp,
                frames::ROBOT,
                frames::CAMERA_COLOR,
                robot_from_camera,
            ));
        }
        sink.write(
            topics::TRANSFORMS,
            log_time_ns,
            &FrameTransforms { transforms },
        )
        .map_err(MapError::Sink)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downscaling_averages_blocks() {
        // 4x2 image, scale 2 -> 2x1.
        let source: Vec<u8> = [
            [0u8, 10, 20],
            [2, 12, 22],
            [100, 0, 0],
            [100, 0, 0],
            [4, 14, 24],
            [6, 16, 26],
            [100, 0, 0],
            [104, 0, 4],
        ]
        .concat();
        let mut out = Vec::new();
        downscale_rgb(&source, 4, 2, (2, 1), &mut out);
        assert_eq!(out, vec![3, 13, 23, 101, 0, 1]);
    }

    #[test]
    fn scaled_intrinsics_project_like_the_full_image() {
        let settings = ImageSettings::VIEWING;
        let full = CameraIntrinsics::tl460_rgb();
        let shown = settings.scaled_intrinsics(&full);
        assert_eq!((shown.width_px, shown.height_px), (960, 540));
        let point = [0.1, -0.05, 1.2];
        let (u, v) = full.project(point).expect("in front");
        let (u2, v2) = shown.project(point).expect("in front");
        // Pixel centres: full-image pixel centre u maps to (u + 0.5) / 2 - 0.5.
        assert!(((u + 0.5) / 2.0 - 0.5 - u2).abs() < 1e-9);
        assert!(((v + 0.5) / 2.0 - 0.5 - v2).abs() < 1e-9);
        assert!(
            ImageSettings {
                scale: 0,
                jpeg_quality: 80
            }
            .problem()
            .is_some()
        );
        assert!(
            ImageSettings {
                scale: 2,
                jpeg_quality: 0
            }
            .problem()
            .is_some()
        );
        assert!(ImageSettings::VIEWING.problem().is_none());
    }

    #[test]
    fn encodes_a_decodable_jpeg_of_the_shown_size() {
        let mut frame: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        for (index, value) in frame.rgb.iter_mut().enumerate() {
            *value = (index % 251) as u8;
        }
        let mut encoder = JpegEncoder::new(ImageSettings::VIEWING);
        let jpeg = encoder.encode(&frame).expect("encode");
        assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "JPEG start-of-image marker");
        let decoded =
            image::load_from_memory_with_format(&jpeg, image::ImageFormat::Jpeg).expect("decode");
        assert_eq!((decoded.width(), decoded.height()), (960, 540));
    }
}
