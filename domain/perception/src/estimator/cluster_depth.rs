//! The paper's clustering-based depth estimate ([dual-arm sec. 3.1.3]).
//!
//! DBSCAN over the mask points; the cluster with the most points is the apple; its centroid
//! depth is `z_d`. With `(x_c, y_c, z_c)` the 3D point at the bounding-box centre, the apple is
//! at `z_d / z_c * (x_c, y_c, z_c)`, i.e. on the box-centre ray at depth `z_d`. Because only the
//! camera-facing surface is visible, `z_d` lies in front of the true centre (about 2/3 of the
//! radius for a fully visible fruit); the paper accepts this bias.
//!
//! The paper reports no radius; here it is estimated from the cluster's lateral spread
//! (`radius_from_lateral_spread`). Confidence is the cluster's share of the points
//! times a support factor.

use super::point_clustering::{ClusteringConfig, PointClustering};
use super::{
    Estimator, EstimatorContext, EstimatorInput, EstimatorKind, PositionEstimate,
    radius_from_lateral_spread, support_factor, to_f64,
};

/// Points at which the support factor reaches 63 %.
const SUPPORT_SCALE_POINTS: f64 = 30.0;

/// The paper's estimator.
#[derive(Debug)]
pub struct ClusterDepthEstimator {
    clustering: PointClustering,
}

impl ClusterDepthEstimator {
    pub fn new(config: ClusteringConfig, context: EstimatorContext) -> Self {
        Self {
            clustering: PointClustering::new(config, context),
        }
    }
}

impl Estimator for ClusterDepthEstimator {
    fn kind(&self) -> EstimatorKind {
        EstimatorKind::ClusterDepth
    }

    fn estimate(&mut self, input: &EstimatorInput<'_>) -> Option<PositionEstimate> {
        self.clustering.run(input.points_in_camera_m);
        let (cluster, size) = self.clustering.largest_cluster()?;
        let members = self
            .clustering
            .points()
            .iter()
            .zip(self.clustering.labels())
            .filter(move |(_, label)| **label == cluster)
            .map(|(p, _)| to_f64(p));
        let mut sum = [0.0; 3];
        for p in members.clone() {
            for axis in 0..3 {
                sum[axis] += p[axis];
            }
        }
        let n = f64::from(size);
        let centroid = [sum[0] / n, sum[1] / n, sum[2] / n];
        let z_d = centroid[2];
        let ray = input.box_center_ray;
        if ray[2].is_nan() || ray[2] <= 0.0 || !z_d.is_finite() {
            return None;
        }
        let scale = z_d / ray[2];
        let position = [ray[0] * scale, ray[1] * scale, z_d];
        let radius_m = radius_from_lateral_spread(members, centroid);
        let share = n as f32 / self.clustering.points().len().max(1) as f32;
        Some(PositionEstimate {
            position_in_camera_m: position,
            radius_m,
            confidence: (share * support_factor(size as usize, SUPPORT_SCALE_POINTS))
                .clamp(0.0, 1.0),
            points_used: size,
            fallback: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_points::{CapScene, context, sample_cap};
    use super::*;

    #[test]
    fn depth_is_the_front_surface_on_the_box_ray() {
        let scene = CapScene {
            centre_m: [0.05, -0.02, 1.0],
            radius_m: 0.04,
            noise_scale: 0.0,
            ..CapScene::default()
        };
        let cap = sample_cap(&scene, 1);
        let mut estimator = ClusterDepthEstimator::new(ClusteringConfig::default(), context());
        let estimate = estimator
            .estimate(&EstimatorInput {
                points_in_camera_m: &cap.points,
                box_center_ray: cap.centre_ray,
            })
            .expect("estimate");
        // Noise-free full cap: centroid depth is about 2/3 r in front of the centre.
        let depth_offset = scene.centre_m[2] - estimate.position_in_camera_m[2];
        assert!(
            (depth_offset - 2.0 / 3.0 * scene.radius_m).abs() < 0.004,
            "offset {depth_offset}"
        );
        // On the box-centre ray.
        let ray = cap.centre_ray;
        let p = estimate.position_in_camera_m;
        assert!((p[0] / p[2] - ray[0]).abs() < 1e-9 && (p[1] / p[2] - ray[1]).abs() < 1e-9);
        assert!(
            (estimate.radius_m - scene.radius_m).abs() < 0.006,
            "{estimate:?}"
        );
        assert!(estimate.confidence > 0.9);
    }

    #[test]
    fn no_points_no_estimate() {
        let mut estimator = ClusterDepthEstimator::new(ClusteringConfig::default(), context());
        let input = EstimatorInput {
            points_in_camera_m: &[],
            box_center_ray: [0.0, 0.0, 1.0],
        };
        assert_eq!(estimator.estimate(&input), None);
        let nan = [[f32::NAN; 3]; 10];
        let input = EstimatorInput {
            points_in_camera_m: &nan,
            box_center_ray: [0.0, 0.0, 1.0],
        };
        assert_eq!(estimator.estimate(&input), None);
    }
}
