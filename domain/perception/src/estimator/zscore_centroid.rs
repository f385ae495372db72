//! Centroid of the mask points after Z-score outlier rejection ([fusion sec. II-D-3] fruit
//! localisation: the fruit is the centre of its mask points, [fusion eq. 20] maps it to the
//! robot).
//!
//! The rejection and the centroid are the LiDAR crate's ([`harvest_lidar::localization`], the
//! same code behind the Table-III comparison): each point's depth is standardized and points
//! beyond `threshold` standard deviations are dropped, once. Like the paper's cluster depth the
//! result carries the visible-surface bias.

use harvest_lidar::localization::{centroid, reject_depth_outliers};

use super::{
    Estimator, EstimatorConfigError, EstimatorInput, EstimatorKind, PositionEstimate, check_range,
    radius_from_lateral_spread, support_factor,
};

pub use harvest_lidar::localization::ZScoreConfig;

/// Checks the Z-score settings (config keys `estimator.zscore.*`).
pub fn validate(config: &ZScoreConfig) -> Result<(), EstimatorConfigError> {
    check_range("zscore.threshold", config.threshold, 0.5, 100.0)?;
    check_range("zscore.min_points", config.min_points as f64, 1.0, 1e6)
}

/// Z-score centroid estimator.
#[derive(Debug)]
pub struct ZScoreCentroidEstimator {
    config: ZScoreConfig,
    kept: Vec<[f64; 3]>,
}

impl ZScoreCentroidEstimator {
    pub fn new(config: ZScoreConfig) -> Self {
        Self {
            config,
            kept: Vec::new(),
        }
    }
}

impl Estimator for ZScoreCentroidEstimator {
    fn kind(&self) -> EstimatorKind {
        EstimatorKind::ZScoreCentroid
    }

    fn estimate(&mut self, input: &EstimatorInput<'_>) -> Option<PositionEstimate> {
        let found =
            reject_depth_outliers(input.points_in_camera_m, &self.config, &mut self.kept).ok()?;
        let centre = centroid(&self.kept)?;
        let count = self.kept.len();
        Some(PositionEstimate {
            position_in_camera_m: centre,
            radius_m: radius_from_lateral_spread(self.kept.iter().copied(), centre),
            confidence: (count as f32 / found as f32) * support_factor(count, 30.0),
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
