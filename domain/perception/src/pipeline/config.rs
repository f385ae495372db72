//! [`PerceptionConfig`]: the settings of the perception pipeline.

use serde::{Deserialize, Serialize};

use crate::depth_source::DepthSource;
use crate::detector::DetectorConfig;
use crate::estimator::EstimatorConfig;
use crate::noise_model::DepthNoiseModel;
use crate::registration::DepthRange;
use crate::scan_policy::LaserScanConfig;

/// Pipeline configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerceptionConfig {
    /// The detector and its parameters (`[detector]`, `kind = "color_segmentation"`, the
    /// default, or `"onnx"`; see [`crate::detector::choice`]).
    pub detector: DetectorConfig,
    /// Detections below this confidence are dropped (the paper's detector threshold is 0.3).
    pub min_detection_confidence: f32,
    /// Accepted depth samples, mm.
    pub depth_range: DepthRange,
    /// Depth noise scale of the depth image; default (key left out): the depth source's sensor
    /// ([`DepthSource::noise_model`]: the ToF camera's datasheet accuracy, or the LiDAR's range
    /// error when localizing from the fused cloud).
    pub noise: Option<DepthNoiseModel>,
    pub estimator: EstimatorConfig,
    /// Merge estimates that localize the same fruit.
    pub merge_duplicates: bool,
    /// Two estimates are one fruit when their centres are closer than this times the sum of
    /// their radii.
    pub duplicate_distance_radii: f64,
    /// Detections with fewer registered depth samples are dropped.
    pub min_points_per_apple: u32,
    /// Lower bound of each radius in the duplicate test, metres (the paper's cluster depth
    /// measures small radii on fragments, which would keep their duplicates apart).
    pub duplicate_min_radius_m: f64,
    /// Apples whose confidence is below this are not reported.
    /// Default (key left out): the depth source's ([`DepthSource::min_output_confidence`]).
    pub min_output_confidence: Option<f32>,
    /// Colour and model detections whose mask covers less than this fraction of their fitted fruit's
    /// image disc are dropped (fragments of mostly hidden fruit).
    pub min_visible_fraction: f64,
    /// Tolerance of the depth-agreement check, in depth-noise sigmas at the median depth.
    pub depth_agreement_sigmas: f64,
    /// An over-exposed blob needs this fraction of its expected depth samples.
    pub saturated_blob_min_depth_coverage: f64,
    /// Physical radius range of a depth-confirmed over-exposed blob, metres.
    pub saturated_blob_radius_m: [f64; 2],
    /// A blob whose depth samples are this flat or flatter (sphere over plane mean squared
    /// residual, see [`crate::blob_localization`]) is an occluder, not a fruit.
    pub saturated_blob_max_flatness: f64,
    /// A blob whose supporting samples' lateral centroid lies further than this many radii from
    /// the blob-centre ray is dropped: the samples are a fruit or fragment off the blob's centre
    /// (a fruit in front of the blown-out one, or a mostly hidden fruit).
    pub saturated_blob_max_asymmetry: f64,
    /// Position confidence of a confirmed blob's estimate (see `blob_estimate`).
    pub saturated_blob_position_confidence: f32,
    /// Laser scans of hard apples (`[laser]`; see [`crate::scan_policy`]).
    pub laser: LaserScanConfig,
    /// The depth image to localize from (used by the process, see [`crate::depth_source`]).
    pub depth_source: DepthSource,
}

impl Default for PerceptionConfig {
    fn default() -> Self {
        Self {
            detector: DetectorConfig::default(),
            min_detection_confidence: 0.3,
            depth_range: DepthRange::default(),
            noise: None,
            estimator: EstimatorConfig::default(),
            merge_duplicates: true,
            duplicate_distance_radii: 0.5,
            min_points_per_apple: 3,
            duplicate_min_radius_m: 0.035,
            min_output_confidence: None,
            min_visible_fraction: 0.25,
            depth_agreement_sigmas: 3.0,
            saturated_blob_min_depth_coverage: 0.25,
            saturated_blob_radius_m: [0.025, 0.07],
            saturated_blob_max_flatness: 0.9,
            saturated_blob_max_asymmetry: 0.4,
            saturated_blob_position_confidence: 0.8,
            laser: LaserScanConfig::default(),
            depth_source: DepthSource::Tof,
        }
    }
}

impl PerceptionConfig {
    /// The depth noise scale in use: `noise` when set, else the depth source's.
    pub fn depth_noise(&self) -> DepthNoiseModel {
        self.noise
            .unwrap_or_else(|| self.depth_source.noise_model())
    }

    /// The output confidence threshold in use: `min_output_confidence` when set, else the depth
    /// source's.
    pub fn output_confidence_threshold(&self) -> f32 {
        self.min_output_confidence
            .unwrap_or_else(|| self.depth_source.min_output_confidence())
    }
}
