//! [`PerceptionSetupError`]: why a perception pipeline cannot be built.

use thiserror::Error;

use crate::camera_setup::CameraSetupError;
use crate::detector::color_segmentation::ColorSegmentationConfigError;
use crate::detector::onnx::OnnxDetectorError;
use crate::estimator::EstimatorConfigError;
use crate::registration::DepthRangeError;
use crate::scan_policy::LaserScanConfigError;

/// Why a [`Perception`](super::Perception) cannot be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PerceptionSetupError {
    /// A camera intrinsic or extrinsic parameter is invalid.
    #[error(transparent)]
    Camera(#[from] CameraSetupError),
    /// The colour-segmentation parameters are invalid.
    #[error(transparent)]
    Detector(#[from] ColorSegmentationConfigError),
    /// The ONNX detector cannot start (library, providers, model, layout).
    #[error(transparent)]
    OnnxDetector(#[from] OnnxDetectorError),
    /// The estimator parameters are invalid.
    #[error(transparent)]
    Estimator(#[from] EstimatorConfigError),
    /// The depth range is invalid.
    #[error(transparent)]
    DepthRange(#[from] DepthRangeError),
    /// A laser-scan setting is invalid.
    #[error(transparent)]
    Laser(#[from] LaserScanConfigError),
    /// A pipeline parameter is not finite or outside its range.
    #[error("perception config: {key} = {value} is not finite or outside {min}..={max}")]
    OutOfRange {
        key: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    /// A depth image given in place of the frame's has another size than the frame's.
    #[error("depth override holds {actual} pixels, the frame's depth image {expected}")]
    DepthOverrideSize { expected: usize, actual: usize },
    /// The frame is colour only (its camera has no depth sensor) and no other depth was given:
    /// nothing to localize from.
    #[error(
        "frame {frame_seq} is colour only (its camera has no depth sensor) and no LiDAR depth \
         has been fused for it: perception needs depth_source = lidar_fused \
         (--depth-source lidar-fused --lidar-extrinsic FILE) and clouds on lidar/points"
    )]
    NoDepthSource { frame_seq: u64 },
}
