//! Per-image position candidate of the target apple ([alacs sec. 3], step 3; the paper
//! gives no formula, so this is our design).
//!
//! The laser plane cuts the apple (a sphere of radius `R`, centre `C`) along a circle of radius
//! `r` centred at `c0`, the foot of `C` on the plane. From the triangulated stripe points
//! (eq. 7-8) on the target:
//! 1. keep points within `R + gate_margin_m` of the rough centre (drops background, far leaves);
//! 2. fit the circle in the plane robustly (RANSAC over 3-point circles, then a geometric
//!    least-squares fit on the inliers) giving `c0`, `r` and their covariance;
//! 3. take `R` from the detection's angular radius (`R = |C| sin(atan(radius_px / f))`) and
//!    set `C = c0 + s h n`, `h = sqrt(R^2 - r^2)`, with `n` the plane's unit normal and `s` the
//!    side of the plane the rough centre lies on (the line starts on the apple's left half, so
//!    `C` lies right of the first planes). `R` and `C` are iterated to agree.
//!
//! The candidate carries a predicted standard error (see [`PositionCandidate::predicted_sigma_m`])
//! that [`crate::selection`] uses to pick among the scan's candidates.

use harvest_hw::alacs::LaserPlane;
use nalgebra::{Matrix3, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::extraction::PixelRoi;

/// What the rough localisation (RGB-D detection, transformed into the ALACS camera frame)
/// says about the target apple.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetHint {
    /// Bounding box of the target apple in the ALACS image, pixels.
    pub bbox_px: PixelRoi,
    /// Rough apple centre in the ALACS camera frame, m.
    pub rough_centre_in_camera_m: [f64; 3],
}

impl TargetHint {
    /// Apparent radius of the apple in the image: mean half-side of the box, pixels.
    pub fn radius_px(&self) -> f64 {
        let width = self.bbox_px.u_max_px.saturating_sub(self.bbox_px.u_min_px);
        let height = self.bbox_px.v_max_px.saturating_sub(self.bbox_px.v_min_px);
        0.25 * (width + height) as f64
    }

    /// The box grown by `margin_px` on every side (the extraction's region of interest).
    pub fn roi(&self, margin_px: usize) -> PixelRoi {
        PixelRoi {
            u_min_px: self.bbox_px.u_min_px.saturating_sub(margin_px),
            v_min_px: self.bbox_px.v_min_px.saturating_sub(margin_px),
            u_max_px: self.bbox_px.u_max_px + margin_px,
            v_max_px: self.bbox_px.v_max_px + margin_px,
        }
    }
}

/// Tunables of [`CandidateFitter`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CandidateConfig {
    /// Margin added around the detection box for extraction, pixels.
    pub roi_margin_px: usize,
    /// Fewest stripe points on the apple for a candidate.
    pub min_points: usize,
    /// Points farther than `R + gate_margin_m` from the rough centre are not on the target, m.
    pub gate_margin_m: f64,
    /// Circle inlier threshold (distance to the fitted circle), m.
    pub circle_inlier_m: f64,
    /// 3-point circle hypotheses tried.
    pub circle_hypotheses: usize,
    /// Standard error of the detection's apparent radius, pixels.
    pub radius_sigma_px: f64,
    /// Standard error of the rough centre across the laser plane, m; a rough centre closer than
    /// this to the plane leaves the side of the apple centre in doubt.
    pub rough_sigma_m: f64,
    /// Floor of `h / R` in the error prediction (a plane through the centre has `h = 0`).
    pub min_offset_ratio: f64,
}

impl Default for CandidateConfig {
    fn default() -> Self {
        Self {
            roi_margin_px: 10,
            min_points: 12,
            gate_margin_m: 0.03,
            circle_inlier_m: 0.0015,
            circle_hypotheses: 64,
            radius_sigma_px: 1.0,
            rough_sigma_m: 0.008,
            min_offset_ratio: 0.2,
        }
    }
}

/// One triangulated stripe point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CandidatePoint {
    pub u_px: f64,
    pub v_px: f64,
    pub point_in_camera_m: [f64; 3],
}

/// The apple position one image supports.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PositionCandidate {
    /// Slide position of the image (encoder feedback), m.
    pub slide_position_m: f64,
    /// Estimated apple centre, ALACS camera frame, m.
    pub centre_in_camera_m: [f64; 3],
    /// Centre of the stripe circle (foot of the apple centre on the laser plane), m.
    pub circle_centre_in_camera_m: [f64; 3],
    /// Radius of the stripe circle `r`, m.
    pub circle_radius_m: f64,
    /// Apple radius `R` used, m.
    pub apple_radius_m: f64,
    /// Signed distance from the laser plane to the centre, `s h`, m.
    pub plane_to_centre_m: f64,
    /// Stripe points on the fitted circle.
    pub points_used: usize,
    /// Stripe points discarded (gate or circle outliers).
    pub points_rejected: usize,
    /// RMS distance of the used points to the circle, m.
    pub fit_rms_m: f64,
    /// Predicted standard error of the centre, m: `sqrt(var(c0) + var(h))`, with
    /// `var(h) = (r^2 var(r) + R^2 var(R)) / max(h, min_offset_ratio R)^2` (+ `h^2` when the
    /// side is in doubt), `var(c0)` and `var(r)` from the circle fit and `var(R)` from
    /// `radius_sigma_px`. Planes near the centre (small `h`) and short or noisy stripes
    /// score badly.
    pub predicted_sigma_m: f64,
}

/// Why an image gave no candidate.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum CandidateError {
    /// Too few stripe points on the target (occluded, laser off the apple, or missed).
    #[error("{found} stripe points on the target apple, {needed} needed")]
    TooFewPoints { found: usize, needed: usize },
    /// The stripe points do not form a usable circle (collinear, or no consensus).
    #[error("stripe points on the target form no circle ({detail})")]
    NoCircle { detail: &'static str },
    /// The hint is unusable (empty box, non-finite rough centre).
    #[error("target hint is invalid: {detail}")]
    InvalidHint { detail: String },
}

/// Fits candidates; keeps scratch buffers and the last fit's inliers.
#[derive(Debug, Clone)]
pub struct CandidateFitter {
    config: CandidateConfig,
    gated: Vec<usize>,
    coordinates: Vec<[f64; 2]>,
    scratch: Vec<usize>,
    inliers: Vec<usize>,
}

impl CandidateFitter {
    pub fn new(config: CandidateConfig) -> Self {
        Self {
            config,
            gated: Vec::new(),
            coordinates: Vec::new(),
            scratch: Vec::new(),
            inliers: Vec::new(),
        }
    }

    pub fn config(&self) -> &CandidateConfig {
        &self.config
    }

    /// Indices (into the last `points` argument) of the points the last successful fit used.
    pub fn inliers(&self) -> &[usize] {
        &self.inliers
    }

    /// The candidate supported by `points` (triangulated on `plane` at `slide_position_m`).
    pub fn fit(
        &mut self,
        points: &[CandidatePoint],
        plane: &LaserPlane,
        slide_position_m: f64,
        hint: &TargetHint,
        focal_px: f64,
    ) -> Result<PositionCandidate, CandidateError> {
        self.inliers.clear();
        let rough = hint.rough_centre_in_camera_m;
        let radius_px = hint.radius_px();
        if !rough.iter().all(|c| c.is_finite()) || rough[2] <= 0.0 {
            return Err(CandidateError::InvalidHint {
                detail: format!("rough_centre_in_camera_m = {rough:?}"),
            });
        }
        if radius_px < 1.0 || focal_px.is_nan() || focal_px <= 0.0 {
            return Err(CandidateError::InvalidHint {
                detail: format!("bbox_px = {:?}", hint.bbox_px),
            });
        }
        let angular_sin = (radius_px / focal_px).atan().sin();
        let rough_radius_m = norm(rough) * angular_sin;
        let config = self.config;

        // 1. Gate around the rough centre.
        self.gated.clear();
        self.gated
            .extend(points.iter().enumerate().filter_map(|(index, point)| {
                (norm(sub(point.point_in_camera_m, rough)) <= rough_radius_m + config.gate_margin_m)
                    .then_some(index)
            }));
        if self.gated.len() < config.min_points {
            return Err(CandidateError::TooFewPoints {
                found: self.gated.len(),
                needed: config.min_points,
            });
        }

        // 2. In-plane coordinates around the gated points' mean.
        let normal = plane.unit_normal();
        let vertical = normalize(sub([0.0, 1.0, 0.0], scale(normal, normal[1])));
        let horizontal = cross(normal, vertical);
        let mut mean = [0.0; 3];
        for &index in &self.gated {
            mean = add(mean, points[index].point_in_camera_m);
        }
        mean = scale(mean, 1.0 / self.gated.len() as f64);
        self.coordinates.clear();
        self.coordinates.extend(self.gated.iter().map(|&index| {
            let offset = sub(points[index].point_in_camera_m, mean);
            [dot(offset, vertical), dot(offset, horizontal)]
        }));

        // RANSAC over 3-point circles; radius bounded by the apple's.
        let max_radius_m = 1.5 * rough_radius_m + config.gate_margin_m;
        let mut rng = SmallRng::seed_from_u64(0x5eed_c1c1e);
        let count = self.coordinates.len();
        let mut best_count = 0;
        let mut chosen: Vec<usize> = Vec::new();
        for _ in 0..config.circle_hypotheses {
            let picks = [
                rng.random_range(0..count),
                rng.random_range(0..count),
                rng.random_range(0..count),
            ];
            let [p, q, r] = picks.map(|k| self.coordinates[k]);
            let Some((centre, radius)) = circle_through(p, q, r) else {
                continue;
            };
            if radius > max_radius_m {
                continue;
            }
            self.scratch.clear();
            self.scratch.extend((0..count).filter(|&k| {
                (dist2(self.coordinates[k], centre) - radius).abs() <= config.circle_inlier_m
            }));
            if self.scratch.len() > best_count {
                best_count = self.scratch.len();
                std::mem::swap(&mut chosen, &mut self.scratch);
            }
        }
        if best_count < config.min_points {
            return Err(CandidateError::TooFewPoints {
                found: best_count,
                needed: config.min_points,
            });
        }

        // Least squares on the consensus set: algebraic start, geometric refinement, one more
        // consensus pass with the refined circle.
        let mut fit = fit_circle(&self.coordinates, &chosen).ok_or(CandidateError::NoCircle {
            detail: "collinear points",
        })?;
        self.scratch.clear();
        self.scratch.extend((0..count).filter(|&k| {
            (dist2(self.coordinates[k], fit.centre) - fit.radius_m).abs() <= config.circle_inlier_m
        }));
        if self.scratch.len() >= config.min_points {
            std::mem::swap(&mut chosen, &mut self.scratch);
            fit = fit_circle(&self.coordinates, &chosen).ok_or(CandidateError::NoCircle {
                detail: "collinear points",
            })?;
        }

        // 3. Sphere centre from the circle, the apparent radius and the side of the plane.
        let circle_centre = add(
            mean,
            add(
                scale(vertical, fit.centre[0]),
                scale(horizontal, fit.centre[1]),
            ),
        );
        let rough_side_m = plane.signed_distance_m(rough);
        let side = if rough_side_m < 0.0 { -1.0 } else { 1.0 };
        let mut distance_m = norm(rough);
        let (mut apple_radius_m, mut offset_m, mut centre) = (0.0, 0.0, circle_centre);
        for _ in 0..4 {
            apple_radius_m = distance_m * angular_sin;
            offset_m = (apple_radius_m * apple_radius_m - fit.radius_m * fit.radius_m)
                .max(0.0)
                .sqrt();
            centre = add(circle_centre, scale(normal, side * offset_m));
            distance_m = norm(centre);
        }

        let radius_sigma_m = apple_radius_m * config.radius_sigma_px / radius_px;
        let offset_floor_m = offset_m.max(config.min_offset_ratio * apple_radius_m);
        let mut offset_variance = (fit.radius_m.powi(2) * fit.radius_variance
            + apple_radius_m.powi(2) * radius_sigma_m.powi(2))
            / offset_floor_m.powi(2);
        if rough_side_m.abs() < config.rough_sigma_m {
            offset_variance += offset_m * offset_m;
        }
        let predicted_sigma_m = (fit.centre_variance + offset_variance).sqrt();

        self.inliers.clear();
        self.inliers.extend(chosen.iter().map(|&k| self.gated[k]));
        let candidate = PositionCandidate {
            slide_position_m,
            centre_in_camera_m: centre,
            circle_centre_in_camera_m: circle_centre,
            circle_radius_m: fit.radius_m,
            apple_radius_m,
            plane_to_centre_m: side * offset_m,
            points_used: chosen.len(),
            points_rejected: points.len() - chosen.len(),
            fit_rms_m: fit.rms_m,
            predicted_sigma_m,
        };
        tracing::trace!(?candidate, "position candidate");
        Ok(candidate)
    }
}

/// A circle fitted in plane coordinates with its uncertainty.
#[derive(Debug, Clone, Copy)]
struct CircleFit {
    centre: [f64; 2],
    radius_m: f64,
    rms_m: f64,
    /// var(centre_a) + var(centre_b), m^2.
    centre_variance: f64,
    /// var(radius), m^2.
    radius_variance: f64,
}

/// Kasa algebraic fit, then Gauss-Newton on the geometric distances; covariance from the
/// final Jacobian and the residual variance.
fn fit_circle(coordinates: &[[f64; 2]], subset: &[usize]) -> Option<CircleFit> {
    if subset.len() < 3 {
        return None;
    }
    // Kasa: a^2 + b^2 = 2 a0 a + 2 b0 b + c.
    let mut normal_matrix = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    for &k in subset {
        let [a, b] = coordinates[k];
        let row = Vector3::new(2.0 * a, 2.0 * b, 1.0);
        normal_matrix += row * row.transpose();
        rhs += row * (a * a + b * b);
    }
    let solution = normal_matrix.cholesky()?.solve(&rhs);
    let mut centre = [solution[0], solution[1]];
    let mut radius_m = (solution[2] + centre[0] * centre[0] + centre[1] * centre[1]).sqrt();
    if !radius_m.is_finite() {
        return None;
    }
    let mut jtj = Matrix3::zeros();
    let mut sum_squares = 0.0;
    for _ in 0..5 {
        jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        sum_squares = 0.0;
        for &k in subset {
            let [a, b] = coordinates[k];
            let distance = dist2([a, b], centre).max(1e-12);
            let residual = distance - radius_m;
            let jacobian =
                Vector3::new((centre[0] - a) / distance, (centre[1] - b) / distance, -1.0);
            jtj += jacobian * jacobian.transpose();
            jtr += jacobian * residual;
            sum_squares += residual * residual;
        }
        let step = jtj.cholesky()?.solve(&(-jtr));
        centre = [centre[0] + step[0], centre[1] + step[1]];
        radius_m += step[2];
        if step.norm() < 1e-10 {
            break;
        }
    }
    let dof = subset.len().saturating_sub(3).max(1) as f64;
    let residual_variance = sum_squares / dof;
    let covariance = jtj.try_inverse()? * residual_variance;
    Some(CircleFit {
        centre,
        radius_m,
        rms_m: (sum_squares / subset.len() as f64).sqrt(),
        centre_variance: covariance[(0, 0)] + covariance[(1, 1)],
        radius_variance: covariance[(2, 2)],
    })
}

/// The circle through three points, `None` when they are (nearly) collinear.
fn circle_through(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> Option<([f64; 2], f64)> {
    let (bx, by) = (q[0] - p[0], q[1] - p[1]);
    let (cx, cy) = (r[0] - p[0], r[1] - p[1]);
    let determinant = 2.0 * (bx * cy - by * cx);
    let scale_sq = (bx * bx + by * by).max(cx * cx + cy * cy);
    if determinant.abs() < 1e-9 * scale_sq || scale_sq == 0.0 {
        return None;
    }
    let b2 = bx * bx + by * by;
    let c2 = cx * cx + cy * cy;
    let ux = (cy * b2 - by * c2) / determinant;
    let uy = (bx * c2 - cx * b2) / determinant;
    Some(([p[0] + ux, p[1] + uy], (ux * ux + uy * uy).sqrt()))
}

fn dist2(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: [f64; 3], factor: f64) -> [f64; 3] {
    [a[0] * factor, a[1] * factor, a[2] * factor]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    scale(a, 1.0 / norm(a))
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::alacs::AlacsExtrinsics;

    /// Points where the laser plane at `slide_position_m` cuts a sphere, front arc only.
    fn stripe_on_sphere(
        plane: &LaserPlane,
        centre: [f64; 3],
        radius_m: f64,
        count: usize,
    ) -> Vec<CandidatePoint> {
        let normal = plane.unit_normal();
        let offset = plane.signed_distance_m(centre);
        let foot = sub(centre, scale(normal, offset));
        let circle_radius = (radius_m * radius_m - offset * offset).sqrt();
        let vertical = normalize(sub([0.0, 1.0, 0.0], scale(normal, normal[1])));
        let horizontal = cross(normal, vertical);
        (0..count)
            .map(|k| {
                let angle = std::f64::consts::PI * (k as f64 + 0.5) / count as f64;
                let candidates = [1.0, -1.0].map(|sign| {
                    add(
                        foot,
                        add(
                            scale(vertical, circle_radius * angle.cos()),
                            scale(horizontal, sign * circle_radius * angle.sin()),
                        ),
                    )
                });
                // The camera sees the half nearer to it.
                let point = if candidates[0][2] < candidates[1][2] {
                    candidates[0]
                } else {
                    candidates[1]
                };
                CandidatePoint {
                    u_px: 0.0,
                    v_px: k as f64,
                    point_in_camera_m: point,
                }
            })
            .collect()
    }

    fn hint_for(centre: [f64; 3], radius_m: f64, focal_px: f64) -> TargetHint {
        let distance = norm(centre);
        let radius_px = focal_px * (radius_m / distance).asin().tan();
        let side = (2.0 * radius_px).round() as usize;
        TargetHint {
            bbox_px: PixelRoi {
                u_min_px: 100,
                v_min_px: 100,
                u_max_px: 100 + side,
                v_max_px: 100 + side,
            },
            rough_centre_in_camera_m: add(centre, [0.003, -0.002, 0.015]),
        }
    }

    #[test]
    fn recovers_the_sphere_centre_from_a_clean_stripe() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let plane = extrinsics.laser_plane_in_camera(0.05);
        let normal = plane.unit_normal();
        // A point on the plane at 0.9 m depth, apple centre 2 cm to the plane's +normal side.
        let (sin_a, cos_a) = extrinsics.alpha_rad.sin_cos();
        let on_plane = [
            (0.9 * sin_a - extrinsics.baseline_m(0.05)) / cos_a,
            0.05,
            0.9,
        ];
        let on_plane = sub(on_plane, scale(normal, plane.signed_distance_m(on_plane)));
        let centre = add(on_plane, scale(normal, 0.02));
        let points = stripe_on_sphere(&plane, centre, 0.04, 80);
        let focal_px = 1739.0;
        let hint = hint_for(centre, 0.04, focal_px);
        let mut fitter = CandidateFitter::new(CandidateConfig::default());
        let candidate = fitter
            .fit(&points, &plane, 0.05, &hint, focal_px)
            .expect("candidate");
        let error = norm(sub(candidate.centre_in_camera_m, centre));
        // The only error source is the pixel-rounded apparent radius.
        assert!(error < 1.5e-3, "{error} m, {candidate:?}");
        assert!((candidate.plane_to_centre_m - 0.02).abs() < 1.5e-3);
        assert_eq!(candidate.points_used, 80);
        assert!(candidate.predicted_sigma_m > 0.0 && candidate.predicted_sigma_m < 5e-3);
    }

    #[test]
    fn leaf_points_in_front_are_left_out() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let plane = extrinsics.laser_plane_in_camera(0.0);
        let normal = plane.unit_normal();
        let (sin_a, cos_a) = extrinsics.alpha_rad.sin_cos();
        let on_plane = [(0.8 * sin_a - extrinsics.l0_m) / cos_a, 0.0, 0.8];
        let centre = add(on_plane, scale(normal, 0.025));
        let mut points = stripe_on_sphere(&plane, centre, 0.04, 60);
        // A leaf 3 cm in front of the apple hides 15 rows: there the laser plane meets the leaf,
        // so their points move towards the camera within the plane.
        let vertical = normalize(sub([0.0, 1.0, 0.0], scale(normal, normal[1])));
        let mut towards_camera = cross(normal, vertical);
        if towards_camera[2] > 0.0 {
            towards_camera = scale(towards_camera, -1.0);
        }
        for point in points.iter_mut().take(15) {
            point.point_in_camera_m = add(point.point_in_camera_m, scale(towards_camera, 0.03));
        }
        let hint = hint_for(centre, 0.04, 1739.0);
        let mut fitter = CandidateFitter::new(CandidateConfig::default());
        let candidate = fitter
            .fit(&points, &plane, 0.0, &hint, 1739.0)
            .expect("candidate");
        assert_eq!(candidate.points_used, 45, "{candidate:?}");
        assert!(fitter.inliers().iter().all(|&k| k >= 15));
        assert!(norm(sub(candidate.centre_in_camera_m, centre)) < 2e-3);
    }

    #[test]
    fn too_few_points_is_an_error() {
        let plane = AlacsExtrinsics::paper_table1().laser_plane_in_camera(0.0);
        let hint = hint_for([0.0, 0.0, 1.0], 0.04, 1739.0);
        let mut fitter = CandidateFitter::new(CandidateConfig::default());
        assert!(matches!(
            fitter.fit(&[], &plane, 0.0, &hint, 1739.0),
            Err(CandidateError::TooFewPoints { found: 0, .. })
        ));
        let bad_hint = TargetHint {
            rough_centre_in_camera_m: [f64::NAN, 0.0, 1.0],
            ..hint
        };
        assert!(matches!(
            fitter.fit(&[], &plane, 0.0, &bad_hint, 1739.0),
            Err(CandidateError::InvalidHint { .. })
        ));
    }
}
