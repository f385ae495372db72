//! Raw outcomes collected while the frames are processed; the report is computed from them.

use harvest_perception::depth_source::DepthSource;
use harvest_perception::estimator::EstimatorKind;

use crate::perception::truth::{AppleConditions, FrameApple};

/// What happened to one visible true apple in one frame under one estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AppleOutcome {
    /// Depth of the true centre in the colour camera frame, metres.
    pub depth_m: f64,
    /// Visible fraction of its silhouette, in [0, 1].
    pub visible_fraction: f64,
    pub conditions: AppleConditions,
    /// 3D error of the matched reported apple, metres; `None` when missed.
    pub error_m: Option<f64>,
    /// Matched when the 3D gate is dropped (2D overlap only): the detector found it, whatever
    /// the estimator made of its position.
    pub found_2d: bool,
}

impl AppleOutcome {
    pub fn new(apple: &FrameApple, error_m: Option<f64>, found_2d: bool) -> Self {
        Self {
            depth_m: apple.depth_m,
            visible_fraction: apple.visible_fraction(),
            conditions: apple.conditions,
            error_m,
            found_2d,
        }
    }

    /// At least half of the apple's silhouette is visible.
    pub fn half_visible(&self) -> bool {
        self.visible_fraction >= 0.5
    }
}

/// Time of one [`harvest_perception::node::PerceptionNode::process`] call.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameTiming {
    /// Wall time (includes time the thread was preempted on a loaded machine).
    pub process_ms: f64,
    /// CPU time of the calling thread.
    pub process_cpu_ms: f64,
    /// True apples with at least one visible pixel in the frame.
    pub visible_apples: usize,
}

/// Everything recorded for one estimator on one depth source over the frames of one scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorRecords {
    pub kind: EstimatorKind,
    /// The depth image the estimator localized from.
    pub depth_source: DepthSource,
    /// Apples reported on frames with apples.
    pub detections: usize,
    /// Reported apples not matched to a true apple.
    pub false_positives: usize,
    /// False positives that are second detections of a matched apple.
    pub false_positives_duplicate: usize,
    /// False positives on a true apple in 2D but beyond the 3D gate.
    pub false_positives_mislocalized: usize,
    /// One entry per visible true apple per frame.
    pub apples: Vec<AppleOutcome>,
    pub timings: Vec<FrameTiming>,
    /// Apples reported on each frame of the zero-apple world.
    pub empty_frame_detections: Vec<usize>,
}

impl EstimatorRecords {
    pub fn new(kind: EstimatorKind, depth_source: DepthSource) -> Self {
        Self {
            kind,
            depth_source,
            detections: 0,
            false_positives: 0,
            false_positives_duplicate: 0,
            false_positives_mislocalized: 0,
            apples: Vec::new(),
            timings: Vec::new(),
            empty_frame_detections: Vec::new(),
        }
    }
}
