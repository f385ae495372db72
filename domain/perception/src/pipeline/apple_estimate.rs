//! [`AppleEstimate`]: one apple the pipeline localized in a frame (its output).

use crate::detector::PixelBox;
use crate::estimator::EstimatorKind;

/// One localized apple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AppleEstimate {
    /// Box in the colour image (union of the boxes when detections were merged).
    pub pixel_box: PixelBox,
    /// Visible apple pixels in the colour image.
    pub visible_px: u32,
    /// Detection confidence from the mask, [0, 1].
    pub mask_confidence: f32,
    /// Geometric confidence of the 3D estimate, [0, 1].
    pub position_confidence: f32,
    /// `mask_confidence * position_confidence`.
    pub confidence: f32,
    /// Apple centre in the colour camera frame, metres.
    pub position_in_camera_m: [f64; 3],
    /// Apple centre in the robot frame, metres.
    pub position_in_robot_m: [f64; 3],
    /// Apple radius, metres.
    pub radius_m: f64,
    /// Depth samples supporting the estimate.
    pub points_used: u32,
    pub estimator: EstimatorKind,
    /// The estimator used its fallback model (few points).
    pub fallback: bool,
    /// Number of detections merged into this apple (1 when not merged).
    pub detections_merged: u32,
}
