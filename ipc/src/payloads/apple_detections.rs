//! Perception's output: the apples seen in one camera frame, localized in 3D.

use crate::bounded_vec::BoundedVec;
use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// At most this many apples are reported per frame.
pub const MAX_APPLES_PER_FRAME: usize = 64;

/// Which 3D localization estimator produced a position (code in [`AppleDetection::method`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum LocalizationMethod {
    /// The DBSCAN largest-cluster centroid depth ([dual-arm sec. 2.1]) along the box-centre ray.
    ClusterCentroid = 1,
    /// Robust sphere fit with an apple-radius prior.
    SphereFit = 2,
    /// Refined by an ALACS laser scan.
    LaserScan = 3,
    /// LiDAR-camera fused points (v1 recordings only: from v2 the depth source has its own
    /// field, [`AppleDetection::depth_source`], and `method` names the estimator).
    LidarFusion = 4,
    /// Centroid of the mask points after Z-score outlier rejection.
    ZScoreCentroid = 5,
}

/// Which depth a position was computed from (code in [`AppleDetection::depth_source`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum DepthSourceCode {
    /// The ToF camera's depth image.
    Tof = 1,
    /// The LiDAR cloud fused into the camera geometry.
    LidarFused = 2,
    /// The ALACS laser line (with method [`LocalizationMethod::LaserScan`]).
    LaserLine = 3,
}

/// One apple found in a camera frame, with where it is.
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
    crate::Describe,
)]
pub struct AppleDetection {
    /// Stable within a track of frames when perception can associate, else per frame.
    pub apple_id: u32,
    /// The estimator that produced the position.
    pub method: WireCode<LocalizationMethod>,
    /// The depth the position was computed from.
    pub depth_source: WireCode<DepthSourceCode>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// Centre in the ToF colour-camera frame, metres.
    pub position_in_camera_m: [f64; 3],
    /// Centre in the robot frame, metres (through the camera mounting).
    pub position_in_robot_m: [f64; 3],
    /// Estimated apple radius, metres.
    pub radius_m: f64,
    /// 0..1.
    pub confidence: f32,
    /// Colour-image box: x, y, width, height in pixels.
    pub box_px: [u32; 4],
    /// Pixels of the apple visible (not hidden by leaves) in the colour image.
    pub visible_px: u32,
}

/// The apples perception found in one camera frame (`perception/apples`).
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
#[type_name("harvest.AppleDetections.v2")]
pub struct AppleDetections {
    /// `capture_ns` is the camera frame's capture time; see [`Header`].
    pub header: Header,
    /// `msg_seq` and `capture_ns` of the camera frame these come from.
    pub source_frame_seq: u64,
    /// `capture_ns` of that camera frame.
    pub source_capture_ns: u64,
    /// Time perception spent on the frame.
    pub processing_ns: u64,
    /// The apples found, at most [`MAX_APPLES_PER_FRAME`].
    pub apples: BoundedVec<AppleDetection, MAX_APPLES_PER_FRAME>,
}
