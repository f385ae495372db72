//! 3D apple position from the mask points of one detection.
//!
//! An [`Estimator`] receives the registered mask points (colour camera frame) and the ray through
//! the detection's box centre, and returns a [`PositionEstimate`]. [`EstimatorKind`] selects:
//! - [`EstimatorKind::ClusterDepth`]: the method of [dual-arm sec. 3.1.3], see [`cluster_depth`].
//! - [`EstimatorKind::SphereFit`]: robust sphere fit with a radius prior, see [`sphere_fit`];
//!   removes the visible-surface bias and uses every fragment of an occluded fruit.
//! - [`EstimatorKind::ZScoreCentroid`]: the centroid after Z-score outlier rejection of
//!   [fusion sec. II-D-3], see [`zscore_centroid`].

pub mod cluster_depth;
mod point_clustering;
pub mod sphere_fit;
pub(crate) mod sphere_model;
pub mod zscore_centroid;

use serde::{Deserialize, Serialize};
use thiserror::Error;

pub use point_clustering::ClusteringConfig;
pub use sphere_fit::SphereFitConfig;
pub use zscore_centroid::ZScoreConfig;

use crate::noise_model::DepthNoiseModel;

/// Which estimator the pipeline runs (config key `estimator.kind`, flag `--estimator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorKind {
    /// Paper: DBSCAN, largest cluster's mean depth along the box-centre ray.
    ClusterDepth,
    /// Robust sphere fit (RANSAC + Gauss-Newton with a radius prior).
    SphereFit,
    /// Centroid of the mask points after Z-score outlier rejection ([fusion sec. II-D-3]).
    ZScoreCentroid,
}

impl std::str::FromStr for EstimatorKind {
    type Err = String;

    /// The config-file spelling (`sphere_fit`) or the command line's (`sphere-fit`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|kind| kind.name() == text.replace('-', "_"))
            .ok_or_else(|| {
                format!("unknown estimator {text:?} (cluster-depth, sphere-fit or zscore-centroid)")
            })
    }
}

impl EstimatorKind {
    pub const ALL: [Self; 3] = [Self::ClusterDepth, Self::SphereFit, Self::ZScoreCentroid];

    pub fn name(&self) -> &'static str {
        match self {
            Self::ClusterDepth => "cluster_depth",
            Self::SphereFit => "sphere_fit",
            Self::ZScoreCentroid => "zscore_centroid",
        }
    }
}

/// The mask points of one detection.
#[derive(Debug, Clone, Copy)]
pub struct EstimatorInput<'a> {
    /// Registered mask points in the colour camera frame, metres.
    pub points_in_camera_m: &'a [[f32; 3]],
    /// Ray through the detection box centre with unit z: `(x_c / z_c, y_c / z_c, 1)`.
    pub box_center_ray: [f64; 3],
}

/// One apple position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionEstimate {
    /// Apple centre in the colour camera frame, metres.
    pub position_in_camera_m: [f64; 3],
    /// Apple radius, metres.
    pub radius_m: f64,
    /// Geometric confidence in [0, 1] (support and consistency of the points).
    pub confidence: f32,
    /// Points that support the estimate (cluster members or sphere inliers).
    pub points_used: u32,
    /// True when the estimator fell back to a simpler model (too few points for its method).
    pub fallback: bool,
}

/// Camera properties the estimators need besides their configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorContext {
    /// Depth noise scale of the ToF camera.
    pub noise: DepthNoiseModel,
    /// Focal length of the depth camera (sets the spacing of depth samples), pixels.
    pub depth_focal_px: f64,
}

/// Estimates one apple position from its mask points.
pub trait Estimator {
    fn kind(&self) -> EstimatorKind;

    /// `None` when the points support no position (no apple is invented).
    fn estimate(&mut self, input: &EstimatorInput<'_>) -> Option<PositionEstimate>;

    /// Every apple the points support, best supported first, replacing the contents of `out`.
    /// The default reports the single [`Self::estimate`].
    fn estimate_all(&mut self, input: &EstimatorInput<'_>, out: &mut Vec<PositionEstimate>) {
        out.clear();
        out.extend(self.estimate(input));
    }
}

/// Configuration of all estimators and the choice among them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorConfig {
    pub kind: EstimatorKind,
    pub clustering: ClusteringConfig,
    pub sphere_fit: SphereFitConfig,
    pub zscore: ZScoreConfig,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        Self {
            kind: EstimatorKind::SphereFit,
            clustering: ClusteringConfig::default(),
            sphere_fit: SphereFitConfig::default(),
            zscore: ZScoreConfig::default(),
        }
    }
}

/// An estimator parameter that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EstimatorConfigError {
    /// A real-valued parameter is not finite or outside its range.
    #[error("estimator config: {key} = {value} is not finite or outside {min}..={max}")]
    OutOfRange {
        key: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    /// The depth focal length of the context is not a positive finite number.
    #[error("estimator context: depth focal length {depth_focal_px} px is not positive and finite")]
    DepthFocal { depth_focal_px: f64 },
    /// The depth noise model of the context has negative or non-finite coefficients.
    #[error("estimator context: depth noise model {noise:?} is invalid")]
    Noise { noise: DepthNoiseModel },
}

/// Checks `value` against `min..=max` for config validation.
pub(crate) fn check_range(
    key: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<(), EstimatorConfigError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(())
    } else {
        Err(EstimatorConfigError::OutOfRange {
            key,
            value,
            min,
            max,
        })
    }
}

impl EstimatorConfig {
    pub fn validate(&self) -> Result<(), EstimatorConfigError> {
        self.clustering.validate()?;
        self.sphere_fit.validate()?;
        zscore_centroid::validate(&self.zscore)
    }
}

/// Builds the estimator selected by `config.kind`.
pub fn make_estimator(
    config: &EstimatorConfig,
    context: EstimatorContext,
) -> Result<Box<dyn Estimator + Send>, EstimatorConfigError> {
    config.validate()?;
    if !context.depth_focal_px.is_finite() || context.depth_focal_px <= 0.0 {
        return Err(EstimatorConfigError::DepthFocal {
            depth_focal_px: context.depth_focal_px,
        });
    }
    if !context.noise.is_valid() {
        return Err(EstimatorConfigError::Noise {
            noise: context.noise,
        });
    }
    Ok(match config.kind {
        EstimatorKind::ClusterDepth => Box::new(cluster_depth::ClusterDepthEstimator::new(
            config.clustering,
            context,
        )),
        EstimatorKind::SphereFit => Box::new(sphere_fit::SphereFitEstimator::new(
            config.clustering,
            config.sphere_fit,
            context,
        )),
        EstimatorKind::ZScoreCentroid => {
            Box::new(zscore_centroid::ZScoreCentroidEstimator::new(config.zscore))
        }
    })
}

/// Apple radius from the lateral spread of its visible points: for points spread uniformly over
/// the image disc of a sphere, the RMS distance from the axis through their centroid along
/// `view_dir` is `r / sqrt(2)`.
pub(crate) fn radius_from_lateral_spread(
    points: impl Iterator<Item = [f64; 3]> + Clone,
    centroid: [f64; 3],
) -> f64 {
    let norm = (centroid[0].powi(2) + centroid[1].powi(2) + centroid[2].powi(2)).sqrt();
    if norm <= 0.0 || !norm.is_finite() {
        return 0.0;
    }
    let axis = [centroid[0] / norm, centroid[1] / norm, centroid[2] / norm];
    let mut sum_sq = 0.0;
    let mut count = 0usize;
    for p in points {
        let d = [p[0] - centroid[0], p[1] - centroid[1], p[2] - centroid[2]];
        let along = d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2];
        sum_sq += d[0] * d[0] + d[1] * d[1] + d[2] * d[2] - along * along;
        count += 1;
    }
    if count == 0 {
        return 0.0;
    }
    (2.0 * sum_sq / count as f64).sqrt()
}

/// `1 - exp(-n / scale)`: support factor that saturates with the number of points.
pub(crate) fn support_factor(points: usize, scale: f64) -> f32 {
    (1.0 - (-(points as f64) / scale).exp()) as f32
}

pub(crate) fn to_f64(p: &[f32; 3]) -> [f64; 3] {
    [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]
}

#[cfg(test)]
pub(crate) mod test_points;
