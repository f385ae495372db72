//! Fused fruit localization ([fusion sec. II-D-3]): the points of one fruit are
//! the fused points under its instance mask (`C_P_mask`, see
//! [`crate::fusion::Fusion::points_in_mask`]); outliers from depth discontinuities (mask pixels
//! that see a leaf in front or the background behind) are rejected by their Z-score; the fruit's
//! position is the centre of the remaining points, moved to the robot frame by eq. 20:
//! `R_p = T_C^R * C_P_mask_mean`.
//!
//! Z-score: on each point's depth `z` (camera frame), `s_i = (z_i - mean) / std`; points with
//! `|s_i| > threshold` are dropped, once, as the paper describes. The centre of the visible
//! surface lies in front of the fruit's centre (about half a radius for a fully seen
//! hemisphere); the paper reports this centre, so this module does too: evaluate repeatability
//! (Table III) rather than absolute accuracy with it.

use harvest_ipc::camera_model::RigidTransform;
use serde::{Deserialize, Serialize};

/// Z-score rejection settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ZScoreConfig {
    /// Points whose depth is more than this many standard deviations from the mean are dropped.
    pub threshold: f64,
    /// Fewer points than this (before or after rejection) give no position.
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

/// One localized fruit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FruitPosition {
    /// Centre of the kept points, colour camera frame, metres.
    pub position_in_camera_m: [f64; 3],
    /// The same, robot frame (eq. 20), metres.
    pub position_in_robot_m: [f64; 3],
    pub points_in_mask: usize,
    pub points_kept: usize,
}

/// Why a fruit could not be localized.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LocalizationError {
    #[error("{found} finite points under the mask, need at least {needed}")]
    TooFewPoints { found: usize, needed: usize },
    #[error("{kept} points left after Z-score rejection of {found}, need at least {needed}")]
    TooFewAfterRejection {
        found: usize,
        kept: usize,
        needed: usize,
    },
}

/// Z-score outlier rejection: the finite points of `points_in_camera_m` whose depth lies within
/// `threshold` standard deviations of the mean depth, into `kept` (replaced). Returns the number
/// of finite points it started from.
pub fn reject_depth_outliers(
    points_in_camera_m: &[[f32; 3]],
    config: &ZScoreConfig,
    kept: &mut Vec<[f64; 3]>,
) -> Result<usize, LocalizationError> {
    kept.clear();
    kept.extend(
        points_in_camera_m
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .map(|p| p.map(f64::from)),
    );
    let found = kept.len();
    let needed = config.min_points.max(1);
    if found < needed {
        return Err(LocalizationError::TooFewPoints { found, needed });
    }
    let n = found as f64;
    let mean = kept.iter().map(|p| p[2]).sum::<f64>() / n;
    let std = (kept.iter().map(|p| (p[2] - mean).powi(2)).sum::<f64>() / n).sqrt();
    let limit = config.threshold * std;
    kept.retain(|p| (p[2] - mean).abs() <= limit);
    if kept.len() < needed {
        return Err(LocalizationError::TooFewAfterRejection {
            found,
            kept: kept.len(),
            needed,
        });
    }
    Ok(found)
}

/// Mean of `points`; `None` when empty or not finite.
pub fn centroid(points: &[[f64; 3]]) -> Option<[f64; 3]> {
    let n = points.len() as f64;
    let mut sum = [0.0; 3];
    for p in points {
        for k in 0..3 {
            sum[k] += p[k];
        }
    }
    let centre = sum.map(|s| s / n);
    (!points.is_empty() && centre.iter().all(|v| v.is_finite())).then_some(centre)
}

/// Localizes one fruit from its mask points (camera frame) with Z-score rejection and eq. 20.
pub fn localize_fruit(
    points_in_camera_m: &[[f32; 3]],
    robot_from_camera: &RigidTransform,
    config: &ZScoreConfig,
) -> Result<FruitPosition, LocalizationError> {
    let mut kept = Vec::new();
    let found = reject_depth_outliers(points_in_camera_m, config, &mut kept)?;
    let position_in_camera_m = centroid(&kept).ok_or(LocalizationError::TooFewAfterRejection {
        found,
        kept: 0,
        needed: config.min_points.max(1),
    })?;
    Ok(FruitPosition {
        position_in_camera_m,
        position_in_robot_m: robot_from_camera.apply(position_in_camera_m),
        points_in_mask: found,
        points_kept: kept.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};

    /// Points on the camera-facing cap of a sphere, with range noise, plus background outliers.
    fn synthetic_fruit(
        centre: [f64; 3],
        radius_m: f64,
        sigma_m: f64,
        outliers: usize,
        rng: &mut SmallRng,
    ) -> (Vec<[f32; 3]>, [f64; 3]) {
        let noise = Normal::new(0.0, sigma_m).expect("sigma");
        let mut points = Vec::new();
        let mut surface_sum = [0.0; 3];
        let mut count = 0.0;
        while points.len() < 2000 {
            // Uniform on the sphere, kept on the hemisphere facing the camera at the origin.
            let v: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if !(0.1..=1.0).contains(&norm) || v[2] / norm > 0.0 {
                continue;
            }
            let p: [f64; 3] = std::array::from_fn(|k| centre[k] + radius_m * v[k] / norm);
            for k in 0..3 {
                surface_sum[k] += p[k];
            }
            count += 1.0;
            let range = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let scale = (range + noise.sample(rng)) / range;
            points.push(p.map(|c| (c * scale) as f32));
        }
        for _ in 0..outliers {
            // Background 1 m behind, inside the mask's cone.
            let p = [centre[0], centre[1], centre[2] + 1.0];
            points.push(p.map(|c| c as f32));
        }
        (points, surface_sum.map(|s| s / count))
    }

    #[test]
    fn zscore_rejects_background_and_finds_the_surface_centre() {
        let mut rng = SmallRng::seed_from_u64(3);
        let centre = [0.1, -0.05, 1.2];
        let (points, surface_centre) = synthetic_fruit(centre, 0.04, 0.005, 60, &mut rng);
        let robot_from_camera =
            RigidTransform::from_rpy_translation(0.1, 0.2, -0.3, [1.0, 2.0, 0.5]);
        let fruit = localize_fruit(&points, &robot_from_camera, &ZScoreConfig::default())
            .expect("localized");
        assert_eq!(fruit.points_in_mask, 2060);
        assert!(
            fruit.points_kept <= 2000,
            "outliers kept: {}",
            fruit.points_kept
        );
        for (k, (found, truth)) in fruit
            .position_in_camera_m
            .iter()
            .zip(surface_centre)
            .enumerate()
        {
            let error = found - truth;
            assert!(error.abs() < 0.002, "axis {k}: {error} m");
        }
        let expected_robot = robot_from_camera.apply(fruit.position_in_camera_m);
        assert_eq!(fruit.position_in_robot_m, expected_robot);
        // Without rejection, the 3 % background points would pull the centre back by ~3 cm.
        let loose = ZScoreConfig {
            threshold: 100.0,
            ..ZScoreConfig::default()
        };
        let biased = localize_fruit(&points, &robot_from_camera, &loose).expect("loose");
        assert!(biased.position_in_camera_m[2] - surface_centre[2] > 0.02);
    }

    #[test]
    fn too_few_points_are_refused() {
        let identity = RigidTransform::IDENTITY;
        let config = ZScoreConfig::default();
        let nan = [[f32::NAN; 3]; 10];
        assert_eq!(
            localize_fruit(&nan, &identity, &config),
            Err(LocalizationError::TooFewPoints {
                found: 0,
                needed: 5
            })
        );
        assert!(localize_fruit(&[], &identity, &config).is_err());
    }
}
