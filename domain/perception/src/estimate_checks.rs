//! Consistency checks between a 3D estimate and the detection it came from.
//!
//! - [`depth_agrees`]: the camera sees the fruit's front surface, so the median depth `z_med` of
//!   a mask's points lies between the fruit's nearest point and its centre. A centre `z_c` with
//!   `z_c - z_med` outside `[-t, r + t]`, `t = k sigma(z_med)` (TL460 depth noise), is a fit that
//!   jumped to another surface (e.g. the next tree row 2 m behind a small fragment).
//! - [`visible_fraction`]: the share of the fitted sphere's image disc (`pi (f r / z)^2` pixels)
//!   that the mask covers. Fragments of mostly hidden fruit constrain the centre poorly: in the
//!   evaluation their errors are several times those of fruit more than half visible.
//! - [`SaturatedBlobCheck`]: an over-exposed blob carries no colour evidence, so depth must
//!   confirm it: enough of its area returns depth (white sky returns none), and the blob's image
//!   radius at the estimated depth is an apple's radius (pinhole: `r = rho_px z / f_px`).

use crate::estimator::PositionEstimate;
use crate::noise_model::DepthNoiseModel;

/// Median depth (z, metres) of `points`; `scratch` is reused. `None` when there are no points.
pub fn median_depth_m(points: &[[f32; 3]], scratch: &mut Vec<f32>) -> Option<f64> {
    scratch.clear();
    scratch.extend(points.iter().map(|p| p[2]).filter(|z| z.is_finite()));
    if scratch.is_empty() {
        return None;
    }
    let middle = scratch.len() / 2;
    let (_, value, _) = scratch.select_nth_unstable_by(middle, f32::total_cmp);
    Some(f64::from(*value))
}

/// True when the estimate's centre depth is consistent with the median depth of its mask points:
/// `-t <= z_c - z_med <= r + t` with `t = sigmas * sigma(z_med)`.
pub fn depth_agrees(
    estimate: &PositionEstimate,
    median_depth_m: f64,
    noise: &DepthNoiseModel,
    sigmas: f64,
) -> bool {
    let tolerance_m = sigmas * noise.sigma_m(median_depth_m);
    let offset_m = estimate.position_in_camera_m[2] - median_depth_m;
    offset_m >= -tolerance_m && offset_m <= estimate.radius_m + tolerance_m
}

/// Fraction of the image disc of a sphere of `radius_m` centred at depth `depth_m` (pinhole,
/// focal `focal_px`) that `visible_px` pixels represent; 0 for a degenerate sphere.
pub fn visible_fraction(visible_px: u32, radius_m: f64, depth_m: f64, focal_px: f64) -> f64 {
    let radius_px = focal_px * radius_m / depth_m;
    let disc_px = std::f64::consts::PI * radius_px * radius_px;
    if !disc_px.is_finite() || disc_px <= 0.0 {
        return 0.0;
    }
    f64::from(visible_px) / disc_px
}

/// Image radius of an over-exposed blob, pixels: the radius of a disc of its area, or half its
/// box's longer side when that is larger. The highlight saturates only the apple's own visible
/// pixels, so a leaf across the apple shrinks the blob's area, while the box usually still spans
/// the apple's full diameter in one direction.
pub fn blob_radius_px(visible_px: u32, box_width_px: u32, box_height_px: u32) -> f64 {
    let from_area = (f64::from(visible_px) / std::f64::consts::PI).sqrt();
    let from_box = 0.5 * f64::from(box_width_px.max(box_height_px));
    from_area.max(from_box)
}

/// Depth confirmation of an over-exposed blob detection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SaturatedBlobCheck {
    /// Depth samples expected per colour pixel: `(fx_d fy_d) / (fx_c fy_c)`.
    pub depth_samples_per_color_px: f64,
    /// Colour focal length (mean of fx and fy), pixels.
    pub color_focal_px: f64,
    /// Minimum fraction of the blob's expected depth samples that must be present.
    pub min_depth_coverage: f64,
    /// Accepted physical radius of the blob, metres `[min, max]`.
    pub radius_range_m: [f64; 2],
}

impl SaturatedBlobCheck {
    /// Fraction of the expected depth samples of a blob of `visible_px` colour pixels that
    /// `points` samples represent.
    pub fn depth_coverage(&self, points: usize, visible_px: u32) -> f64 {
        let expected = f64::from(visible_px) * self.depth_samples_per_color_px;
        if expected <= 0.0 {
            return 0.0;
        }
        points as f64 / expected
    }

    /// Physical radius of a blob of image radius `radius_px` seen at `depth_m`, metres.
    pub fn blob_radius_m(&self, radius_px: f64, depth_m: f64) -> f64 {
        radius_px * depth_m / self.color_focal_px
    }

    /// True when the depth confirms an apple: enough coverage of the blob's `visible_px`, and
    /// the blob's radius (`radius_px`, see [`blob_radius_px`]) at the estimate's centre depth in
    /// the accepted range.
    pub fn confirms(
        &self,
        points: usize,
        visible_px: u32,
        radius_px: f64,
        estimate: &PositionEstimate,
    ) -> bool {
        let radius_m = self.blob_radius_m(radius_px, estimate.position_in_camera_m[2]);
        self.depth_coverage(points, visible_px) >= self.min_depth_coverage
            && radius_m >= self.radius_range_m[0]
            && radius_m <= self.radius_range_m[1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(z_m: f64) -> PositionEstimate {
        PositionEstimate {
            position_in_camera_m: [0.0, 0.0, z_m],
            radius_m: 0.04,
            confidence: 1.0,
            points_used: 100,
            fallback: false,
        }
    }

    #[test]
    fn median_depth_is_the_middle_value() {
        let points = [[0.0, 0.0, 3.0], [0.0, 0.0, 1.0], [0.0, 0.0, 2.0]];
        let mut scratch = Vec::new();
        assert_eq!(median_depth_m(&points, &mut scratch), Some(2.0));
        assert_eq!(median_depth_m(&[], &mut scratch), None);
    }

    #[test]
    fn centre_behind_the_surface_by_up_to_a_radius_agrees() {
        let noise = DepthNoiseModel::TL460;
        // Front surface median 1.20 m; sigma(1.2 m) = 7 mm, tolerance 21 mm.
        assert!(depth_agrees(&estimate(1.227), 1.2, &noise, 3.0));
        assert!(depth_agrees(&estimate(1.19), 1.2, &noise, 3.0));
        assert!(!depth_agrees(&estimate(1.17), 1.2, &noise, 3.0));
        assert!(!depth_agrees(&estimate(1.27), 1.2, &noise, 3.0));
        // A fragment's fit jumped to the next row.
        assert!(!depth_agrees(&estimate(3.5), 1.2, &noise, 3.0));
    }

    #[test]
    fn visible_fraction_of_a_known_disc() {
        // 40 mm at 1.6 m with f = 1600 px: a 40 px radius disc of 5027 px.
        let disc_px = std::f64::consts::PI * 1600.0;
        let half = (0.5 * disc_px) as u32;
        assert!((visible_fraction(half, 0.04, 1.6, 1600.0) - 0.5).abs() < 1e-3);
        assert_eq!(visible_fraction(100, 0.0, 1.6, 1600.0), 0.0);
    }

    #[test]
    fn blob_needs_depth_coverage_and_apple_size() {
        let check = SaturatedBlobCheck {
            depth_samples_per_color_px: 0.1,
            color_focal_px: 1600.0,
            min_depth_coverage: 0.25,
            radius_range_m: [0.025, 0.07],
        };
        // A 40 mm fruit at 1.6 m: 40 px radius, 5027 px, 503 depth samples expected.
        let visible_px = (std::f64::consts::PI * 40.0 * 40.0) as u32;
        let radius_px = blob_radius_px(visible_px, 80, 80);
        assert!((radius_px - 40.0).abs() < 0.1);
        assert!((check.blob_radius_m(radius_px, 1.6) - 0.04).abs() < 1e-3);
        assert!(check.confirms(300, visible_px, radius_px, &estimate(1.6)));
        // White sky: no depth.
        assert!(!check.confirms(10, visible_px, radius_px, &estimate(1.6)));
        // The same blob on the next row 5 m away would be a 125 mm object.
        assert!(!check.confirms(300, visible_px, radius_px, &estimate(5.0)));
        // Half the fruit behind a leaf: half the area, but the box still spans the diameter
        // vertically, so the fruit keeps its size.
        let half = visible_px / 2;
        assert!((blob_radius_px(half, 40, 80) - 40.0).abs() < 1e-9);
        assert!(check.confirms(150, half, blob_radius_px(half, 40, 80), &estimate(1.6)));
    }
}
