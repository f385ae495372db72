//! Per-frame and cumulative perception statistics, including counters for bad input.

use crate::frame::FrameError;

/// Timings of the pipeline stages of one frame, microseconds (diagnostics only).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StageTimings {
    pub detect_us: u64,
    pub register_us: u64,
    pub estimate_us: u64,
    pub total_us: u64,
}

/// What happened in one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    /// Set when the frame was rejected as a whole (wrong buffer or image size).
    pub rejection: Option<FrameError>,
    /// Fraction of the colour image that is over-exposed, in [0, 1].
    pub saturated_fraction: f32,
    /// Depth samples registered into the colour image.
    pub depth_registered_px: u32,
    /// Depth samples equal to 0 (no return).
    pub depth_zero_px: u32,
    /// Non-zero depth samples outside the working range.
    pub depth_out_of_range_px: u32,
    /// Valid depth samples that fall outside the colour image.
    pub depth_outside_color_px: u32,
    /// Detections reported by the detector.
    pub detections: u32,
    /// Detections below the confidence threshold (dropped).
    pub detections_below_confidence: u32,
    /// Detections whose mask received no depth sample (dropped).
    pub detections_without_depth: u32,
    /// Detections for which the estimator returned no position (dropped).
    pub estimates_failed: u32,
    /// Estimates dropped for a non-finite position or a depth outside the working range.
    pub estimates_rejected: u32,
    /// Estimates that used the estimator's fallback model.
    pub estimates_fallback: u32,
    /// Detections merged into another because both localized the same fruit.
    pub duplicates_merged: u32,
    /// Further fruit found inside a detection's mask (fruit hidden behind fruit).
    pub extra_fruit_in_detections: u32,
    /// Over-exposed blob detections that the depth did not confirm as an apple (dropped).
    pub saturated_blobs_rejected: u32,
    /// Over-exposed blob detections confirmed by depth.
    pub saturated_blobs_confirmed: u32,
    /// Estimates whose centre disagrees with the median depth of their mask (dropped).
    pub estimates_inconsistent: u32,
    /// Estimates below `min_output_confidence` (dropped).
    pub estimates_below_confidence: u32,
    /// Estimates whose mask covers less than `min_visible_fraction` of their fruit (dropped).
    pub estimates_mostly_hidden: u32,
    /// Apples reported.
    pub apples: u32,
    pub timings: StageTimings,
}

/// Counters accumulated over all frames since construction.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PerceptionStats {
    pub frames: u64,
    /// Frames rejected because the colour frame was malformed or of the wrong size.
    pub frames_rejected_rgb: u64,
    /// Frames rejected because the depth frame was malformed or of the wrong size.
    pub frames_rejected_depth: u64,
    /// Frames the detector failed on (a learned detector's runtime error).
    pub frames_detector_failed: u64,
    /// Frames whose depth image registered no sample at all (all zero / out of range).
    pub frames_without_depth: u64,
    /// Frames with more than half of the colour image over-exposed.
    pub frames_mostly_saturated: u64,
    pub detections: u64,
    pub detections_below_confidence: u64,
    pub detections_without_depth: u64,
    pub estimates_failed: u64,
    pub estimates_rejected: u64,
    pub estimates_fallback: u64,
    pub duplicates_merged: u64,
    pub extra_fruit_in_detections: u64,
    pub saturated_blobs_rejected: u64,
    pub saturated_blobs_confirmed: u64,
    pub estimates_inconsistent: u64,
    pub estimates_below_confidence: u64,
    pub estimates_mostly_hidden: u64,
    pub apples: u64,
}

impl PerceptionStats {
    /// Adds one frame's statistics.
    pub fn accumulate(&mut self, frame: &FrameStats) {
        self.frames += 1;
        match &frame.rejection {
            Some(
                FrameError::RgbEmpty { .. }
                | FrameError::RgbBufferSize { .. }
                | FrameError::RgbSizeMismatch { .. },
            ) => self.frames_rejected_rgb += 1,
            Some(FrameError::DetectorFailed { .. }) => self.frames_detector_failed += 1,
            Some(_) => self.frames_rejected_depth += 1,
            None => {
                if frame.depth_registered_px == 0 {
                    self.frames_without_depth += 1;
                }
            }
        }
        if frame.saturated_fraction > 0.5 {
            self.frames_mostly_saturated += 1;
        }
        self.detections += u64::from(frame.detections);
        self.detections_below_confidence += u64::from(frame.detections_below_confidence);
        self.detections_without_depth += u64::from(frame.detections_without_depth);
        self.estimates_failed += u64::from(frame.estimates_failed);
        self.estimates_rejected += u64::from(frame.estimates_rejected);
        self.estimates_fallback += u64::from(frame.estimates_fallback);
        self.duplicates_merged += u64::from(frame.duplicates_merged);
        self.extra_fruit_in_detections += u64::from(frame.extra_fruit_in_detections);
        self.saturated_blobs_rejected += u64::from(frame.saturated_blobs_rejected);
        self.saturated_blobs_confirmed += u64::from(frame.saturated_blobs_confirmed);
        self.estimates_inconsistent += u64::from(frame.estimates_inconsistent);
        self.estimates_below_confidence += u64::from(frame.estimates_below_confidence);
        self.estimates_mostly_hidden += u64::from(frame.estimates_mostly_hidden);
        self.apples += u64::from(frame.apples);
    }
}
