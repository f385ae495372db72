//! One apple sphere from all the interval scan's stripe circles (our design; the paper selects
//! one candidate, section 3 step 3).
//!
//! Why: a single image's candidate places the centre `h = sqrt(R^2 - r^2)` off its laser plane,
//! with the apple radius `R` taken from outside the scan (the request's rough radius). An error
//! `dR` moves the centre by `R dR / h` along the plane normal, i.e. mostly sideways and in depth:
//! with a ToF radius a few millimetres off, that is 5-40 mm. The scan itself measures `R`: the
//! slide moves the laser plane in known steps (eq. 4-5: all planes share the unit normal `n` and
//! differ in the offset `o_k = (L0 - d_k) / |n_raw|`), and each plane cuts the sphere along a
//! circle of radius `r_k` centred at the foot of the centre on that plane. With `s = n . C` the
//! centre's signed distance to plane `k` is `s + o_k`, so
//!
//! `r_k^2 + o_k^2 = (R^2 - s^2) - 2 s o_k`,
//!
//! a straight line in `o_k`: a least-squares line through the scan's circles gives `s` (slope)
//! and `R` (intercept); the centre is the circles' common in-plane foot plus `s n`. No prior
//! radius and no side-of-plane guess are needed. Circles whose radius disagrees with the fitted
//! sphere by more than [`FusionConfig::max_residual_m`] (a stripe cut short by a leaf, a fit on
//! a short arc) are dropped one at a time, worst first.

use harvest_hw::alacs::AlacsExtrinsics;
use serde::{Deserialize, Serialize};

use crate::candidate::PositionCandidate;

/// Tunables of [`fuse_slices`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FusionConfig {
    /// Fewest circles for a fused sphere (3: two unknowns and one check).
    pub min_slices: usize,
    /// Largest disagreement between a circle's radius and the fitted sphere's, m.
    pub max_residual_m: f64,
    /// Plausible apple radii, m.
    pub radius_range_m: [f64; 2],
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            min_slices: 3,
            max_residual_m: 1.5e-3,
            radius_range_m: [0.015, 0.08],
        }
    }
}

/// The sphere the scan's circles agree on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FusedSphere {
    /// Apple centre, ALACS camera frame, m.
    pub centre_in_camera_m: [f64; 3],
    /// Apple radius measured by the scan, m.
    pub radius_m: f64,
    /// Circles used.
    pub slices_used: usize,
    /// RMS of the used circles' radius residuals, m.
    pub rms_residual_m: f64,
}

/// Fits one sphere to the circles of `candidates` (one per image, any slide positions), or
/// `None` when fewer than `min_slices` consistent circles remain or the fit is implausible.
pub fn fuse_slices(
    candidates: &[PositionCandidate],
    extrinsics: &AlacsExtrinsics,
    config: &FusionConfig,
) -> Option<FusedSphere> {
    let normal = extrinsics.laser_plane_in_camera(0.0).unit_normal();
    // (o_k, r_k, in-plane foot c0_k - (n . c0_k) n) of each circle.
    let mut slices: Vec<([f64; 3], f64, f64)> = candidates
        .iter()
        .map(|candidate| {
            let plane = extrinsics.laser_plane_in_camera(candidate.slide_position_m);
            let normal_length = dot(plane.normal, plane.normal).sqrt();
            let offset_m = plane.offset_m / normal_length;
            let foot = candidate.circle_centre_in_camera_m;
            let along = dot(normal, foot);
            let in_plane = std::array::from_fn(|k| foot[k] - along * normal[k]);
            (in_plane, offset_m, candidate.circle_radius_m)
        })
        .filter(|(in_plane, offset_m, radius_m)| {
            in_plane.iter().all(|c| c.is_finite()) && offset_m.is_finite() && radius_m.is_finite()
        })
        .collect();
    loop {
        if slices.len() < config.min_slices.max(2) {
            return None;
        }
        let (s_m, radius_m) = fit_line(&slices)?;
        let residual = |&(_, offset_m, r_m): &([f64; 3], f64, f64)| {
            let t_m = s_m + offset_m;
            let predicted_m = (radius_m * radius_m - t_m * t_m).max(0.0).sqrt();
            (r_m - predicted_m).abs()
        };
        let (worst, worst_m) = slices
            .iter()
            .enumerate()
            .map(|(index, slice)| (index, residual(slice)))
            .max_by(|a, b| a.1.total_cmp(&b.1))?;
        if worst_m > config.max_residual_m {
            slices.swap_remove(worst);
            continue;
        }
        if !(config.radius_range_m[0]..=config.radius_range_m[1]).contains(&radius_m) {
            return None;
        }
        let count = slices.len() as f64;
        let foot: [f64; 3] =
            std::array::from_fn(|k| slices.iter().map(|(p, _, _)| p[k]).sum::<f64>() / count);
        let rms_residual_m =
            (slices.iter().map(|s| residual(s).powi(2)).sum::<f64>() / count).sqrt();
        return Some(FusedSphere {
            centre_in_camera_m: std::array::from_fn(|k| foot[k] + s_m * normal[k]),
            radius_m,
            slices_used: slices.len(),
            rms_residual_m,
        });
    }
}

/// Least-squares line `y = a + b x` through `(o_k, r_k^2 + o_k^2)`; returns `(s, R)` with
/// `s = -b / 2`, `R = sqrt(a + s^2)`, or `None` when the offsets do not spread or `R^2 <= 0`.
fn fit_line(slices: &[([f64; 3], f64, f64)]) -> Option<(f64, f64)> {
    let count = slices.len() as f64;
    let mean_x = slices.iter().map(|s| s.1).sum::<f64>() / count;
    let ys = |s: &([f64; 3], f64, f64)| s.2 * s.2 + s.1 * s.1;
    let mean_y = slices.iter().map(ys).sum::<f64>() / count;
    let sxx: f64 = slices.iter().map(|s| (s.1 - mean_x).powi(2)).sum();
    let sxy: f64 = slices
        .iter()
        .map(|s| (s.1 - mean_x) * (ys(s) - mean_y))
        .sum();
    if sxx < 1e-12 {
        return None;
    }
    let slope = sxy / sxx;
    let intercept = mean_y - slope * mean_x;
    let s_m = -0.5 * slope;
    let radius_squared = intercept + s_m * s_m;
    (radius_squared > 0.0).then(|| (s_m, radius_squared.sqrt()))
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The candidate an exact circle of the sphere (`centre`, `radius_m`) on the plane at `d`
    /// gives (only the fields fusion reads are meaningful).
    fn exact_slice(
        extrinsics: &AlacsExtrinsics,
        centre: [f64; 3],
        radius_m: f64,
        slide_position_m: f64,
    ) -> PositionCandidate {
        let plane = extrinsics.laser_plane_in_camera(slide_position_m);
        let normal = plane.unit_normal();
        let t_m = plane.signed_distance_m(centre);
        PositionCandidate {
            slide_position_m,
            centre_in_camera_m: centre,
            circle_centre_in_camera_m: std::array::from_fn(|k| centre[k] - t_m * normal[k]),
            circle_radius_m: (radius_m * radius_m - t_m * t_m).sqrt(),
            apple_radius_m: radius_m,
            plane_to_centre_m: t_m,
            points_used: 40,
            points_rejected: 0,
            fit_rms_m: 1e-4,
            predicted_sigma_m: 1e-3,
        }
    }

    fn scan_slices(
        extrinsics: &AlacsExtrinsics,
        centre: [f64; 3],
        radius_m: f64,
    ) -> Vec<PositionCandidate> {
        // First plane 2 cm left of the centre, then 1 cm steps (the interval scan).
        let normal_length = dot(
            extrinsics.laser_plane_in_camera(0.0).normal,
            extrinsics.laser_plane_in_camera(0.0).normal,
        )
        .sqrt();
        let first_m = extrinsics
            .laser_plane_in_camera(0.0)
            .signed_distance_m(centre)
            * normal_length
            - 0.02 * normal_length;
        (0..5)
            .map(|k| exact_slice(extrinsics, centre, radius_m, first_m + 0.01 * k as f64))
            .collect()
    }

    #[test]
    fn exact_circles_give_the_sphere_back() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let centre = [0.04, -0.05, 0.95];
        let slices = scan_slices(&extrinsics, centre, 0.036);
        let fused = fuse_slices(&slices, &extrinsics, &FusionConfig::default()).expect("fused");
        assert_eq!(fused.slices_used, 5);
        assert!((fused.radius_m - 0.036).abs() < 1e-9, "{fused:?}");
        for (got, want) in fused.centre_in_camera_m.iter().zip(centre) {
            assert!((got - want).abs() < 1e-9, "{fused:?}");
        }
        // Any three circles are enough; two are refused.
        assert!(fuse_slices(&slices[1..4], &extrinsics, &FusionConfig::default()).is_some());
        assert!(fuse_slices(&slices[..2], &extrinsics, &FusionConfig::default()).is_none());
    }

    #[test]
    fn a_circle_cut_short_by_a_leaf_is_dropped() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let centre = [0.0, 0.02, 1.05];
        let mut slices = scan_slices(&extrinsics, centre, 0.04);
        slices[3].circle_radius_m -= 0.008;
        let fused = fuse_slices(&slices, &extrinsics, &FusionConfig::default()).expect("fused");
        assert_eq!(fused.slices_used, 4);
        let error_m = (0..3)
            .map(|k| (fused.centre_in_camera_m[k] - centre[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(error_m < 1e-9, "{error_m}");
    }
}
