//! Centroid of the mask points after Z-score outlier rejection (LiDAR-camera fusion paper,
//! fruit localisation: the fruit is the centre of its mask points, eq. 20 maps it to the robot).
//!
//! Each point's range `|p|` is standardized, `z_i = (|p_i| - mean) / std`; points with
//! `|z_i| > threshold` are dropped and the centroid of the rest is the fruit position. Like the
//! paper's cluster depth it carries the visible-surface bias.

use serde::{Deserialize, Serialize};

use super::{
    Estimator, EstimatorConfigError, EstimatorInput, EstimatorKind, PositionEstimate, check_range,
    radius_from_lateral_spread, support_factor, to_f64,
};

/// Z-score rejection settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZScoreConfig {
    /// Points whose range deviates more than this many standard deviations are outliers.
    pub threshold: f64,
    /// Minimum number of points for an estimate.
    pub min_points: usize,
}

impl Default for ZScoreConfig {
    fn default() -> Self {
        Self {
            threshold: 2.5,
            min_points: 5,
        }
    }
}

impl ZScoreConfig {
    pub fn validate(&self) -> Result<(), EstimatorConfigError> {
        check_range("zscore.threshold", self.threshold, 0.5, 100.0)?;
        check_range("zscore.min_points", self.min_points as f64, 1.0, 1e6)
    }
}

/// Z-score centroid estimator.
#[derive(Debug)]
pub struct ZScoreCentroidEstimator {
    config: ZScoreConfig,
    ranges: Vec<f64>,
}

impl ZScoreCentroidEstimator {
    pub fn new(config: ZScoreConfig) -> Self {
        Self {
            config,
            ranges: Vec::new(),
        }
    }
}

impl Estimator for ZScoreCentroidEstimator {
    fn kind(&self) -> EstimatorKind {
        EstimatorKind::ZScoreCentroid
    }

    fn estimate(&mut self, input: &EstimatorInput<'_>) -> Option<PositionEstimate> {
        let finite = |p: &&[f32; 3]| p.iter().all(|v| v.is_finite());
        self.ranges.clear();
        self.ranges.extend(
            input
                .points_in_camera_m
                .iter()
                .filter(finite)
                .map(to_f64)
                .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()),
        );
        let n = self.ranges.len();
        if n < self.config.min_points {
            return None;
        }
        let mean = self.ranges.iter().sum::<f64>() / n as f64;
        let variance = self.ranges.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / n as f64;
        let limit = self.config.threshold * variance.sqrt();
        let kept = input
            .points_in_camera_m
            .iter()
            .filter(finite)
            .map(to_f64)
            .zip(self.ranges.iter())
            .filter(move |(_, r)| (**r - mean).abs() <= limit)
            .map(|(p, _)| p);
        let mut sum = [0.0; 3];
        let mut count = 0usize;
        for p in kept.clone() {
            for axis in 0..3 {
                sum[axis] += p[axis];
            }
            count += 1;
        }
        if count < self.config.min_points {
            return None;
        }
        let c = count as f64;
        let centroid = [sum[0] / c, sum[1] / c, sum[2] / c];
        if centroid.iter().any(|v| !v.is_finite()) {
            return None;
        }
        Some(PositionEstimate {
            position_in_camera_m: centroid,
            radius_m: radius_from_lateral_spread(kept, centroid),
            confidence: (c as f32 / n as f32) * support_factor(count, 30.0),
            points_used: count as u32,
            fallback: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_points::{CapScene, sample_cap};
    use super::*;

    #[test]
    fn far_outliers_are_rejected() {
        let scene = CapScene {
            centre_m: [0.0, 0.0, 1.2],
            ..CapScene::default()
        };
        let mut cap = sample_cap(&scene, 3);
        let clean = ZScoreCentroidEstimator::new(ZScoreConfig::default())
            .estimate(&EstimatorInput {
                points_in_camera_m: &cap.points,
                box_center_ray: cap.centre_ray,
            })
            .expect("estimate");
        // 3 % of the points far behind the fruit.
        let outliers = cap.points.len() / 33;
        for p in cap.points.iter_mut().take(outliers) {
            p[2] += 1.5;
        }
        let with_outliers = ZScoreCentroidEstimator::new(ZScoreConfig::default())
            .estimate(&EstimatorInput {
                points_in_camera_m: &cap.points,
                box_center_ray: cap.centre_ray,
            })
            .expect("estimate");
        assert!(with_outliers.points_used as usize <= cap.points.len() - outliers);
        let shift = (with_outliers.position_in_camera_m[2] - clean.position_in_camera_m[2]).abs();
        assert!(shift < 0.003, "outliers moved the centroid by {shift} m");
        assert!(
            ZScoreCentroidEstimator::new(ZScoreConfig::default())
                .estimate(&EstimatorInput {
                    points_in_camera_m: &cap.points[..3],
                    box_center_ray: cap.centre_ray,
                })
                .is_none()
        );
    }
}
