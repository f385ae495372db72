//! Improved estimator: robust sphere fit with an apple-radius prior.
//!
//! The cluster depth of [dual-arm sec. 3.1.3] measures the camera-facing surface, so it sits
//! about 2/3 of a radius in front of the fruit centre, and an occluder that splits the fruit's
//! points keeps only the biggest fragment (the failure mode named in the paper's 4.3). This
//! estimator models the fruit as a sphere of radius 35-50 mm:
//! 1. DBSCAN (same adaptive radius as the paper) drops isolated noise and flying pixels; the
//!    points of *every* cluster remain candidates, so fragments of one fruit all contribute.
//! 2. RANSAC: three random candidates define a sphere of the prior radius (or their
//!    circumradius if larger) whose centre lies behind them; the hypothesis with the lowest
//!    truncated squared residual (MSAC) over the camera-facing candidates wins. Inlier tolerance
//!    `max(min_inlier_tolerance_m, inlier_sigmas * sigma(z))` with the TL460 noise scale.
//! 3. Gauss-Newton with Huber weights and the Gaussian radius prior refines centre and radius on
//!    the inliers; a radius outside the prior interval is clamped and the centre refitted.
//! 4. Fruit hidden behind fruit in one mask (a cluster the 2D split could not separate): the
//!    candidates the first sphere does not explain are fitted again, up to
//!    `max_spheres_per_detection` spheres; a further sphere needs `secondary_min_fraction` of the
//!    candidates and must lie within `secondary_max_depth_gap_m` behind the first (same canopy
//!    layer; background foliage and flying pixels lie further back).
//! 5. Every sphere must show significant curvature: `n * (plane MSE - sphere MSE) / sigma^2`
//!    over its inliers reaches `min_curvature_evidence`. A leaf, or background seen past a fruit
//!    edge because of the depth-colour baseline, fits a plane as well as a sphere and is refused.
//! 6. With too few points, or when the fit is implausible or flat, it falls back to the median surface
//!    depth pushed back by `fallback_depth_offset_radii` prior radii along the box-centre ray
//!    (the mean depth of a uniformly sampled visible hemisphere lies 2/3 r in front of the
//!    centre), flagged as fallback with low confidence.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};
use tracing::trace;

use super::point_clustering::{ClusteringConfig, PointClustering};
use super::sphere_model::{
    RefineParams, Sphere, plane_rms, refine, refine_along_rays, sphere_through_three,
};
use super::{
    Estimator, EstimatorConfigError, EstimatorContext, EstimatorInput, EstimatorKind,
    PositionEstimate, check_range, support_factor, to_f64,
};
use crate::dbscan::NOISE;

/// Sphere-fit settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SphereFitConfig {
    /// Smallest plausible apple radius, metres.
    pub radius_min_m: f64,
    /// Largest plausible apple radius, metres.
    pub radius_max_m: f64,
    /// Mean of the Gaussian radius prior, metres.
    pub radius_prior_m: f64,
    /// Standard deviation of the radius prior, metres.
    pub radius_prior_sigma_m: f64,
    /// RANSAC hypotheses per apple.
    pub ransac_iterations: usize,
    /// At most this many candidates (uniform stride) score each hypothesis.
    pub ransac_score_points: usize,
    /// Inlier tolerance in depth-noise sigmas.
    pub inlier_sigmas: f64,
    /// Lower bound of the inlier tolerance, metres.
    pub min_inlier_tolerance_m: f64,
    /// Candidates needed for a sphere fit; fewer use the fallback.
    pub min_fit_points: usize,
    /// Gauss-Newton iterations per refinement.
    pub refine_iterations: usize,
    /// Huber threshold of the refinement, in depth-noise sigmas.
    pub huber_sigmas: f64,
    /// Fallback: centre depth = median surface depth + this many prior radii.
    pub fallback_depth_offset_radii: f64,
    /// RANSAC random seed (the estimate is deterministic for given points).
    pub seed: u64,
    /// At most this many fruit are extracted from one detection's points.
    pub max_spheres_per_detection: usize,
    /// A further fruit in one detection needs at least this fraction of its candidate points.
    pub secondary_min_fraction: f64,
    /// A further fruit lies at most this far behind the first one (same canopy layer), metres.
    pub secondary_max_depth_gap_m: f64,
    /// Minimum curvature evidence of a sphere (chi-square scale, see `curvature_evidence`);
    /// flatter point sets use the fallback (first fruit) or end the search (further fruit).
    pub min_curvature_evidence: f64,
}

impl Default for SphereFitConfig {
    fn default() -> Self {
        Self {
            radius_min_m: 0.035,
            radius_max_m: 0.050,
            radius_prior_m: 0.0425,
            radius_prior_sigma_m: 0.005,
            ransac_iterations: 64,
            ransac_score_points: 400,
            inlier_sigmas: 2.0,
            min_inlier_tolerance_m: 0.003,
            min_fit_points: 20,
            refine_iterations: 10,
            huber_sigmas: 1.5,
            fallback_depth_offset_radii: 2.0 / 3.0,
            seed: 0x5eed_a991e,
            max_spheres_per_detection: 3,
            secondary_min_fraction: 0.15,
            secondary_max_depth_gap_m: 0.3,
            min_curvature_evidence: 16.0,
        }
    }
}

impl SphereFitConfig {
    pub fn validate(&self) -> Result<(), EstimatorConfigError> {
        check_range("sphere_fit.radius_min_m", self.radius_min_m, 0.005, 0.5)?;
        check_range(
            "sphere_fit.radius_max_m",
            self.radius_max_m,
            self.radius_min_m,
            0.5,
        )?;
        check_range(
            "sphere_fit.radius_prior_m",
            self.radius_prior_m,
            self.radius_min_m,
            self.radius_max_m,
        )?;
        check_range(
            "sphere_fit.radius_prior_sigma_m",
            self.radius_prior_sigma_m,
            1e-4,
            0.5,
        )?;
        check_range(
            "sphere_fit.ransac_iterations",
            self.ransac_iterations as f64,
            1.0,
            1e5,
        )?;
        check_range(
            "sphere_fit.ransac_score_points",
            self.ransac_score_points as f64,
            10.0,
            1e7,
        )?;
        check_range("sphere_fit.inlier_sigmas", self.inlier_sigmas, 0.1, 100.0)?;
        check_range(
            "sphere_fit.min_inlier_tolerance_m",
            self.min_inlier_tolerance_m,
            0.0,
            0.1,
        )?;
        check_range(
            "sphere_fit.min_fit_points",
            self.min_fit_points as f64,
            4.0,
            1e6,
        )?;
        check_range(
            "sphere_fit.refine_iterations",
            self.refine_iterations as f64,
            1.0,
            1000.0,
        )?;
        check_range("sphere_fit.huber_sigmas", self.huber_sigmas, 0.1, 100.0)?;
        check_range(
            "sphere_fit.fallback_depth_offset_radii",
            self.fallback_depth_offset_radii,
            0.0,
            1.0,
        )?;
        check_range(
            "sphere_fit.max_spheres_per_detection",
            self.max_spheres_per_detection as f64,
            1.0,
            16.0,
        )?;
        check_range(
            "sphere_fit.secondary_min_fraction",
            self.secondary_min_fraction,
            0.0,
            1.0,
        )?;
        check_range(
            "sphere_fit.secondary_max_depth_gap_m",
            self.secondary_max_depth_gap_m,
            0.0,
            10.0,
        )?;
        check_range(
            "sphere_fit.min_curvature_evidence",
            self.min_curvature_evidence,
            0.0,
            1e6,
        )
    }
}

/// Support scale (points) of the confidence.
const SUPPORT_SCALE_POINTS: f64 = 40.0;
/// Confidence factor of a further fruit found in the same detection.
const SECONDARY_CONFIDENCE_FACTOR: f32 = 0.8;
/// Confidence ceiling of a fallback estimate.
const FALLBACK_CONFIDENCE: f32 = 0.3;

/// The sphere-fit estimator with its scratch buffers.
#[derive(Debug)]
pub struct SphereFitEstimator {
    config: SphereFitConfig,
    context: EstimatorContext,
    clustering: PointClustering,
    candidates: Vec<[f64; 3]>,
    inliers: Vec<[f64; 3]>,
    depths: Vec<f64>,
    results: Vec<PositionEstimate>,
}

impl SphereFitEstimator {
    pub fn new(
        clustering: ClusteringConfig,
        config: SphereFitConfig,
        context: EstimatorContext,
    ) -> Self {
        Self {
            config,
            context,
            clustering: PointClustering::new(clustering, context),
            candidates: Vec::new(),
            inliers: Vec::new(),
            depths: Vec::new(),
            results: Vec::new(),
        }
    }

    fn tolerance_m(&self, depth_m: f64) -> f64 {
        (self.config.inlier_sigmas * self.context.noise.sigma_m(depth_m))
            .max(self.config.min_inlier_tolerance_m)
    }

    fn is_inlier(&self, sphere: &Sphere, p: [f64; 3]) -> bool {
        let tolerance = self.tolerance_m(p[2]);
        sphere.residual(p).abs() <= tolerance && sphere.faces_camera(p, tolerance)
    }

    /// Best RANSAC hypothesis over `self.candidates`.
    fn ransac(&self) -> Option<Sphere> {
        let n = self.candidates.len();
        let mut rng = SmallRng::seed_from_u64(self.config.seed);
        let stride = n.div_ceil(self.config.ransac_score_points).max(1);
        let mut best: Option<(f64, Sphere)> = None;
        for _ in 0..self.config.ransac_iterations {
            let i = rng.random_range(0..n);
            let j = rng.random_range(0..n);
            let k = rng.random_range(0..n);
            if i == j || j == k || i == k {
                continue;
            }
            let Some(sphere) = sphere_through_three(
                self.candidates[i],
                self.candidates[j],
                self.candidates[k],
                self.config.radius_prior_m,
                self.config.radius_max_m,
            ) else {
                continue;
            };
            if sphere.centre[2] <= 0.0 {
                continue;
            }
            let mut cost = 0.0;
            for &p in self.candidates.iter().step_by(stride) {
                let tolerance = self.tolerance_m(p[2]);
                let residual = sphere.residual(p);
                cost += if residual.abs() <= tolerance && sphere.faces_camera(p, tolerance) {
                    residual * residual
                } else {
                    tolerance * tolerance
                };
            }
            if best.is_none_or(|(best_cost, _)| cost < best_cost) {
                best = Some((cost, sphere));
            }
        }
        best.map(|(_, sphere)| sphere)
    }

    fn collect_inliers(&mut self, sphere: &Sphere) {
        let mut inliers = std::mem::take(&mut self.inliers);
        inliers.clear();
        inliers.extend(
            self.candidates
                .iter()
                .copied()
                .filter(|&p| self.is_inlier(sphere, p)),
        );
        self.inliers = inliers;
    }

    fn refine_params(&self, fix_radius: bool) -> RefineParams {
        RefineParams {
            radius_prior_m: self.config.radius_prior_m,
            radius_prior_sigma_m: self.config.radius_prior_sigma_m,
            huber_sigmas: self.config.huber_sigmas,
            iterations: self.config.refine_iterations,
            fix_radius,
        }
    }

    /// RANSAC + refinement; `(sphere, inliers, radius clamped)` or `None` when implausible.
    fn fit(&mut self) -> Option<(Sphere, usize, bool)> {
        let hypothesis = self.ransac()?;
        self.collect_inliers(&hypothesis);
        if self.inliers.len() < self.config.min_fit_points / 2 {
            return None;
        }
        let noise = self.context.noise;
        let mut sphere = refine(
            &self.inliers,
            &noise,
            hypothesis,
            &self.refine_params(false),
        )?;
        // Second pass on the inliers of the refined sphere.
        self.collect_inliers(&sphere);
        if self.inliers.len() < self.config.min_fit_points / 2 {
            return None;
        }
        sphere = refine(&self.inliers, &noise, sphere, &self.refine_params(false))?;
        // Final pass with the error along the viewing rays (removes the isotropic model's pull
        // towards the camera); a radius outside the prior interval is clamped and refitted.
        let lateral_sigma_per_m = 1.0 / self.context.depth_focal_px;
        let mut clamped = false;
        for fix_radius in [false, true] {
            sphere = refine_along_rays(
                &self.inliers,
                &noise,
                lateral_sigma_per_m,
                sphere,
                &self.refine_params(fix_radius),
            )?;
            let clamped_radius = sphere
                .radius
                .clamp(self.config.radius_min_m, self.config.radius_max_m);
            if clamped_radius == sphere.radius {
                break;
            }
            sphere.radius = clamped_radius;
            clamped = true;
        }
        self.collect_inliers(&sphere);
        let inliers = self.inliers.len();
        // The centre must lie behind the visible surface.
        self.depths.clear();
        self.depths.extend(self.inliers.iter().map(|p| p[2]));
        let surface_depth = median(&mut self.depths)?;
        if inliers < self.config.min_fit_points / 2 || sphere.centre[2] <= surface_depth {
            return None;
        }
        Some((sphere, inliers, clamped))
    }

    /// Median-depth fallback along the box-centre ray.
    fn fallback(&mut self, ray: [f64; 3]) -> Option<PositionEstimate> {
        let points = self.candidates.len();
        self.depths.clear();
        self.depths.extend(self.candidates.iter().map(|p| p[2]));
        let surface_depth = median(&mut self.depths)?;
        if ray[2].is_nan() || ray[2] <= 0.0 {
            return None;
        }
        let depth =
            surface_depth + self.config.fallback_depth_offset_radii * self.config.radius_prior_m;
        let scale = depth / ray[2];
        Some(PositionEstimate {
            position_in_camera_m: [ray[0] * scale, ray[1] * scale, depth],
            radius_m: self.config.radius_prior_m,
            confidence: FALLBACK_CONFIDENCE * support_factor(points, SUPPORT_SCALE_POINTS),
            points_used: points as u32,
            fallback: true,
        })
    }
}

/// Median of `values` (reordered in place); `None` when empty.
fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let middle = values.len() / 2;
    let (_, value, _) = values.select_nth_unstable_by(middle, f64::total_cmp);
    Some(*value)
}

impl SphereFitEstimator {
    /// Fills `self.candidates` with the points of DBSCAN clusters; `false` when DBSCAN found no
    /// cluster (then `self.candidates` holds every finite point).
    fn prepare_candidates(&mut self, points: &[[f32; 3]]) -> bool {
        let clusters = self.clustering.run(points);
        self.candidates.clear();
        if clusters == 0 {
            self.candidates
                .extend(self.clustering.points().iter().map(to_f64));
            return false;
        }
        self.candidates.extend(
            self.clustering
                .points()
                .iter()
                .zip(self.clustering.labels())
                .filter(|(_, label)| **label != NOISE)
                .map(|(p, _)| to_f64(p)),
        );
        true
    }

    /// Removes the candidates explained by `sphere` (near its surface or inside it).
    fn remove_explained(&mut self, sphere: &Sphere) {
        let mut candidates = std::mem::take(&mut self.candidates);
        candidates.retain(|&p| sphere.residual(p) > 2.0 * self.tolerance_m(p[2]));
        self.candidates = candidates;
    }

    /// Evidence that the current inliers are curved like `sphere` rather than flat:
    /// `n * (plane MSE - sphere MSE) / mean(sigma^2)`, roughly chi-square distributed with one
    /// degree of freedom when the surface is flat. A leaf, or a patch too small to show the
    /// fruit's curvature, scores near zero.
    fn curvature_evidence(&self, sphere: &Sphere) -> f64 {
        let n = self.inliers.len();
        if n < 4 {
            return 0.0;
        }
        let count = n as f64;
        let sphere_mse = self
            .inliers
            .iter()
            .map(|&p| sphere.residual(p).powi(2))
            .sum::<f64>()
            / count;
        let noise_var = self
            .inliers
            .iter()
            .map(|p| self.context.noise.sigma_m(p[2]).powi(2))
            .sum::<f64>()
            / count;
        let Some(plane_rms) = plane_rms(&self.inliers) else {
            return 0.0;
        };
        count * (plane_rms * plane_rms - sphere_mse) / noise_var
    }
}

impl Estimator for SphereFitEstimator {
    fn kind(&self) -> EstimatorKind {
        EstimatorKind::SphereFit
    }

    fn estimate(&mut self, input: &EstimatorInput<'_>) -> Option<PositionEstimate> {
        let mut results = std::mem::take(&mut self.results);
        self.estimate_all(input, &mut results);
        let first = results.first().copied();
        self.results = results;
        first
    }

    /// Sequential fit: the best-supported sphere first, then further spheres on the candidates
    /// it does not explain (fruit hidden behind fruit in one mask), while enough remain. Every
    /// sphere must be significantly curved; a further one must also hold
    /// `secondary_min_fraction` of the candidates.
    fn estimate_all(&mut self, input: &EstimatorInput<'_>, out: &mut Vec<PositionEstimate>) {
        out.clear();
        if !self.prepare_candidates(input.points_in_camera_m) {
            // Too sparse for DBSCAN: the fallback uses whatever finite points there are.
            out.extend(self.fallback(input.box_center_ray));
            return;
        }
        let total = self.candidates.len();
        let secondary_min = (self.config.secondary_min_fraction * total as f64).ceil() as usize;
        while out.len() < self.config.max_spheres_per_detection
            && self.candidates.len() >= self.config.min_fit_points
            && (out.is_empty() || self.candidates.len() >= secondary_min)
        {
            let Some((sphere, inliers, clamped)) = self.fit() else {
                break;
            };
            let curved = self.curvature_evidence(&sphere) >= self.config.min_curvature_evidence;
            let secondary_ok = out.first().is_none_or(|first| {
                inliers >= secondary_min
                    && sphere.centre[2] - first.position_in_camera_m[2]
                        <= self.config.secondary_max_depth_gap_m
            });
            if !curved || !secondary_ok {
                break;
            }
            let share = inliers as f32 / self.candidates.len() as f32;
            let mut confidence = share * support_factor(inliers, SUPPORT_SCALE_POINTS);
            if clamped {
                confidence *= 0.8;
            }
            if !out.is_empty() {
                confidence *= SECONDARY_CONFIDENCE_FACTOR;
            }
            trace!(
                total,
                inliers,
                radius_m = sphere.radius,
                clamped,
                sphere = out.len(),
                "sphere fit"
            );
            out.push(PositionEstimate {
                position_in_camera_m: sphere.centre,
                radius_m: sphere.radius,
                confidence: confidence.clamp(0.0, 1.0),
                points_used: inliers as u32,
                fallback: false,
            });
            self.remove_explained(&sphere);
        }
        if !out.is_empty() {
            return;
        }
        // Few points or an implausible sphere: the largest cluster's median depth, pushed back.
        if let Some((cluster, _)) = self.clustering.largest_cluster() {
            self.candidates.clear();
            self.candidates.extend(
                self.clustering
                    .points()
                    .iter()
                    .zip(self.clustering.labels())
                    .filter(|(_, label)| **label == cluster)
                    .map(|(p, _)| to_f64(p)),
            );
        }
        trace!(total, "sphere fit fell back to median depth");
        out.extend(self.fallback(input.box_center_ray));
    }
}

#[cfg(test)]
mod tests {
    use super::super::cluster_depth::ClusterDepthEstimator;
    use super::super::test_points::{CapScene, Occluder, context, error_m, sample_cap};
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn sphere_fit() -> SphereFitEstimator {
        SphereFitEstimator::new(
            ClusteringConfig::default(),
            SphereFitConfig::default(),
            context(),
        )
    }

    fn paper() -> ClusterDepthEstimator {
        ClusterDepthEstimator::new(ClusteringConfig::default(), context())
    }

    /// Mean 3D error of both estimators over random fruit, as (sphere fit, paper) in metres.
    fn mean_errors(
        occluder: Option<Occluder>,
        flying_fraction: f64,
        seed: u64,
    ) -> (f64, f64, usize) {
        let mut rng = SmallRng::seed_from_u64(seed);
        let (mut fit_sum, mut paper_sum, mut fallbacks) = (0.0, 0.0, 0);
        let trials = 40;
        for trial in 0..trials {
            let z = rng.random_range(0.7..1.8);
            let scene = CapScene {
                centre_m: [rng.random_range(-0.3..0.3), rng.random_range(-0.2..0.2), z],
                radius_m: rng.random_range(0.036..0.048),
                noise_scale: 1.0,
                occluder,
                flying_fraction,
            };
            let cap = sample_cap(&scene, seed * 1000 + trial);
            let input = EstimatorInput {
                points_in_camera_m: &cap.points,
                box_center_ray: cap.centre_ray,
            };
            let fit = sphere_fit().estimate(&input).expect("sphere fit estimate");
            let reference = paper().estimate(&input).expect("paper estimate");
            fallbacks += usize::from(fit.fallback);
            fit_sum += error_m(fit.position_in_camera_m, scene.centre_m);
            paper_sum += error_m(reference.position_in_camera_m, scene.centre_m);
        }
        (
            fit_sum / trials as f64,
            paper_sum / trials as f64,
            fallbacks,
        )
    }

    #[test]
    fn sphere_fit_beats_cluster_depth_on_noisy_caps() {
        let (fit, paper, fallbacks) = mean_errors(None, 0.0, 1);
        eprintln!("clean caps: sphere fit {fit:.4} m, paper {paper:.4} m, fallbacks {fallbacks}");
        assert_eq!(fallbacks, 0);
        assert!(fit < 0.010, "sphere fit mean error {fit} m");
        assert!(fit < 0.5 * paper, "sphere fit {fit} m vs paper {paper} m");
    }

    #[test]
    fn sphere_fit_survives_occluder_fragmentation_and_flying_pixels() {
        let occluder = Occluder {
            half_width_radii: 0.35,
            offset_radii: 0.1,
            gap_m: 0.04,
            in_mask_fraction: 0.3,
        };
        let (fit, paper, fallbacks) = mean_errors(Some(occluder), 0.3, 2);
        eprintln!(
            "occluded caps: sphere fit {fit:.4} m, paper {paper:.4} m, fallbacks {fallbacks}"
        );
        assert_eq!(fallbacks, 0);
        assert!(fit < 0.014, "sphere fit mean error {fit} m");
        assert!(fit < 0.5 * paper, "sphere fit {fit} m vs paper {paper} m");
    }

    /// Points of `back` whose camera ray hits `front` first are hidden.
    fn hide_behind(front: &CapScene, back: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let [cx, cy, cz] = front.centre_m;
        let r = front.radius_m;
        back.iter()
            .copied()
            .filter(|p| {
                let d = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
                let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                let dc = d[0] * cx + d[1] * cy + d[2] * cz;
                let cc = cx * cx + cy * cy + cz * cz;
                dc * dc - dd * (cc - r * r) < 0.0
            })
            .collect()
    }

    #[test]
    fn fruit_hidden_behind_fruit_is_found_as_a_second_sphere() {
        let front = CapScene {
            centre_m: [0.0, 0.0, 1.0],
            radius_m: 0.042,
            ..CapScene::default()
        };
        let back = CapScene {
            centre_m: [0.055, 0.01, 1.12],
            radius_m: 0.04,
            ..CapScene::default()
        };
        let mut points = sample_cap(&front, 21).points;
        let back_points = hide_behind(&front, &sample_cap(&back, 22).points);
        points.extend_from_slice(&back_points);
        let mut estimator = sphere_fit();
        let mut out = Vec::new();
        estimator.estimate_all(
            &EstimatorInput {
                points_in_camera_m: &points,
                box_center_ray: [0.02, 0.0, 1.0],
            },
            &mut out,
        );
        assert_eq!(out.len(), 2, "{out:?}");
        assert!(
            error_m(out[0].position_in_camera_m, front.centre_m) < 0.012,
            "{out:?}"
        );
        assert!(
            error_m(out[1].position_in_camera_m, back.centre_m) < 0.015,
            "{out:?}"
        );
        assert!(out[1].confidence <= SECONDARY_CONFIDENCE_FACTOR);
        // `estimate` reports the best-supported fruit only.
        let single = estimator
            .estimate(&EstimatorInput {
                points_in_camera_m: &points,
                box_center_ray: [0.02, 0.0, 1.0],
            })
            .expect("estimate");
        assert_eq!(single, out[0]);
    }

    #[test]
    fn leaf_patch_next_to_a_fruit_is_not_a_second_fruit() {
        let fruit = CapScene {
            centre_m: [0.0, 0.0, 1.0],
            radius_m: 0.042,
            ..CapScene::default()
        };
        let mut points = sample_cap(&fruit, 31).points;
        let mut rng = SmallRng::seed_from_u64(32);
        let leaf_count = points.len() / 3;
        // A flat, slightly tilted leaf 10 cm behind, 5 x 5 cm.
        for _ in 0..leaf_count {
            let (x, y) = (
                rng.random_range(0.03..0.08),
                rng.random_range(-0.025..0.025),
            );
            let z = 1.1 + 0.2 * x + rng.random_range(-0.004..0.004);
            points.push([x as f32, y as f32, z as f32]);
        }
        let mut out = Vec::new();
        sphere_fit().estimate_all(
            &EstimatorInput {
                points_in_camera_m: &points,
                box_center_ray: [0.0, 0.0, 1.0],
            },
            &mut out,
        );
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(error_m(out[0].position_in_camera_m, fruit.centre_m) < 0.012);
    }

    #[test]
    fn radius_is_recovered_within_the_prior_interval() {
        let scene = CapScene {
            centre_m: [0.0, 0.05, 0.9],
            radius_m: 0.045,
            noise_scale: 0.5,
            ..CapScene::default()
        };
        let cap = sample_cap(&scene, 11);
        let estimate = sphere_fit()
            .estimate(&EstimatorInput {
                points_in_camera_m: &cap.points,
                box_center_ray: cap.centre_ray,
            })
            .expect("estimate");
        assert!((estimate.radius_m - 0.045).abs() < 0.004, "{estimate:?}");
        assert!(estimate.confidence > 0.5);
        assert!(estimate.points_used > 100);
    }

    #[test]
    fn few_points_fall_back_with_low_confidence() {
        let scene = CapScene {
            centre_m: [0.0, 0.0, 1.0],
            radius_m: 0.04,
            noise_scale: 0.0,
            ..CapScene::default()
        };
        let cap = sample_cap(&scene, 5);
        // Only the 8 points nearest the centre of the cap.
        let mut points = cap.points.clone();
        points.sort_by(|a, b| (a[0].hypot(a[1])).total_cmp(&b[0].hypot(b[1])));
        points.truncate(8);
        let estimate = sphere_fit()
            .estimate(&EstimatorInput {
                points_in_camera_m: &points,
                box_center_ray: cap.centre_ray,
            })
            .expect("fallback estimate");
        assert!(estimate.fallback);
        assert!(estimate.confidence <= FALLBACK_CONFIDENCE);
        // Front surface at 0.96 m pushed back by 2/3 of 42.5 mm.
        let expected_depth = 0.96 + 2.0 / 3.0 * 0.0425;
        assert!(
            (estimate.position_in_camera_m[2] - expected_depth).abs() < 0.002,
            "{estimate:?}"
        );
        assert!(
            sphere_fit()
                .estimate(&EstimatorInput {
                    points_in_camera_m: &[],
                    box_center_ray: cap.centre_ray,
                })
                .is_none()
        );
    }

    #[test]
    fn non_finite_points_and_rays_do_not_invent_apples() {
        let points = [[f32::NAN, 0.0, 1.0]; 50];
        let input = EstimatorInput {
            points_in_camera_m: &points,
            box_center_ray: [0.0, 0.0, 1.0],
        };
        assert!(sphere_fit().estimate(&input).is_none());
        let scene = CapScene::default();
        let cap = sample_cap(&scene, 3);
        let bad_ray = EstimatorInput {
            points_in_camera_m: &cap.points[..5],
            box_center_ray: [f64::NAN, 0.0, f64::NAN],
        };
        assert!(sphere_fit().estimate(&bad_ray).is_none());
    }
}

#[cfg(test)]
mod range_noise_tests {
    use super::super::test_points::{CapScene, DEPTH_FOCAL_PX, error_m, sample_cap};
    use super::*;
    use crate::noise_model::DepthNoiseModel;

    /// Median 3D error and mean signed depth error (estimate - truth) over 40 fully visible caps
    /// at 1.5 m whose depth noise is `noise_scale` times the TL460's, keeping every
    /// `keep_every`-th sample (a sparser LiDAR), with the estimator told `noise`.
    fn errors(noise: DepthNoiseModel, noise_scale: f64, keep_every: usize) -> (f64, f64) {
        let context = EstimatorContext {
            noise,
            depth_focal_px: DEPTH_FOCAL_PX,
        };
        let mut estimator = SphereFitEstimator::new(
            ClusteringConfig::default(),
            SphereFitConfig::default(),
            context,
        );
        let (mut errors, mut depth_errors) = (Vec::new(), Vec::new());
        for trial in 0..40u64 {
            let scene = CapScene {
                centre_m: [0.05, -0.02, 1.5],
                radius_m: 0.042,
                noise_scale,
                ..CapScene::default()
            };
            let cap = sample_cap(&scene, trial);
            let points: Vec<[f32; 3]> = cap.points.iter().step_by(keep_every).copied().collect();
            let input = EstimatorInput {
                points_in_camera_m: &points,
                box_center_ray: cap.centre_ray,
            };
            let estimate = estimator.estimate(&input).expect("estimate");
            assert!(!estimate.fallback, "{estimate:?}");
            errors.push(error_m(estimate.position_in_camera_m, scene.centre_m));
            depth_errors.push(estimate.position_in_camera_m[2] - scene.centre_m[2]);
        }
        errors.sort_by(f64::total_cmp);
        let mean_depth_error = depth_errors.iter().sum::<f64>() / depth_errors.len() as f64;
        (errors[errors.len() / 2], mean_depth_error)
    }

    #[test]
    fn range_noise_does_not_pull_the_centre_towards_the_camera() {
        // ToF: the TL460 noise (7.75 mm at 1.5 m), every depth pixel.
        let (median, bias) = errors(DepthNoiseModel::TL460, 1.0, 1);
        assert!(median < 0.002, "ToF median error {median} m");
        assert!(bias.abs() < 0.001, "ToF mean depth error {bias} m");
        // LiDAR-like: 2 cm range noise, a quarter of the samples (the isotropic fit alone puts
        // the centre about sigma^2 / r in front of the truth).
        let lidar = DepthNoiseModel {
            base_m: 0.02,
            fraction_of_depth: 0.0,
        };
        let (median, bias) = errors(lidar, 0.02 / DepthNoiseModel::TL460.sigma_m(1.5), 4);
        assert!(median < 0.006, "LiDAR median error {median} m");
        assert!(bias.abs() < 0.005, "LiDAR mean depth error {bias} m");
    }
}
