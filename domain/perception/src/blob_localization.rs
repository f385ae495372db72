//! Position of a blown-out fruit from its over-exposed blob and the blob's depth samples.
//!
//! Sunlight that saturates a fruit in the colour image also degrades its ToF depth (several
//! times the usual noise, many dropouts), which defeats a free sphere fit. But the blob is the
//! fruit's image, so the centre lies on the blob-centre ray `d = (x/z, y/z, 1)` and only its depth
//! `z_c` is unknown. With the radius `r` known (from the blob's size, clamped to the apple prior),
//! a depth sample `p` at lateral distance `rho` from the ray lies on the sphere's front surface
//! when `p_z = z_c - sqrt(r^2 - rho^2)`, so every sample inside the silhouette votes
//! `z_c = p_z + sqrt(r^2 - rho^2)`. Occluding leaves vote too near, background seen past the rim
//! too far, and their votes spread out, while the fruit's votes pile up: the estimate is the
//! median of the densest window of votes of width `2 w`, `w = max(window_sigmas * sigma(z),
//! min_half_window_m)`. Two passes: the second uses the radius the blob implies at the first
//! depth.
//!
//! A leaf covering most of the blob also piles its votes up (at its own depth plus about `r`),
//! but its samples are flat: over the samples of the winning window, the ratio of the mean
//! squared sphere residual `(|p - c| - r)^2` to the mean squared distance from their
//! least-squares plane (`flatness`) is well below 1 for a fruit and near or above 1 for a leaf.
//! A fruit seen whole supports its window from all around the ray; the lateral centroid of the
//! supporting samples, in radii (`asymmetry`), is near 0 for it and about `4 / (3 pi) = 0.42`
//! for a half-visible one; a fruit in front of the blown-out one, or a small fragment, scores
//! higher.

use crate::estimator::sphere_model::plane_rms;
use crate::noise_model::DepthNoiseModel;

/// Parameters of [`BlobLocalizer`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlobLocalizerParams {
    /// Apple radius range, metres (the estimate's radius is clamped to it).
    pub radius_range_m: [f64; 2],
    /// Radius used before the depth is known, metres.
    pub radius_prior_m: f64,
    /// Blob radius over fruit radius (the saturated disc slightly exceeds the fruit).
    pub blob_over_fruit_radius: f64,
    /// Half width of the vote window, in (un-degraded) depth-noise sigmas.
    pub window_sigmas: f64,
    /// Lower bound of the half width of the vote window, metres.
    pub min_half_window_m: f64,
    pub noise: DepthNoiseModel,
}

/// Result of [`BlobLocalizer::locate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlobLocation {
    /// Fruit centre in the colour camera frame, metres.
    pub centre_m: [f64; 3],
    pub radius_m: f64,
    /// Votes in the winning window.
    pub votes: u32,
    /// Samples inside the silhouette (all votes).
    pub samples: u32,
    /// Mean squared sphere residual over mean squared plane residual of the winning window's
    /// samples: well below 1 for a curved fruit, about 1 or more for a flat occluder.
    pub flatness: f64,
    /// Distance of the supporting samples' lateral centroid from the ray, in radii.
    pub asymmetry: f64,
}

/// Scratch buffer of the vote.
#[derive(Debug, Default)]
pub struct BlobLocalizer {
    /// `(vote, sample index)`.
    votes: Vec<(f64, u32)>,
    window: Vec<[f64; 3]>,
}

impl BlobLocalizer {
    /// Locates the fruit of a blob of radius `blob_radius_px` (colour pixels, focal `focal_px`)
    /// whose centre ray is `ray` (unit z), from its depth samples. `None` without votes.
    pub fn locate(
        &mut self,
        points: &[[f32; 3]],
        ray: [f64; 3],
        blob_radius_px: f64,
        focal_px: f64,
        params: &BlobLocalizerParams,
    ) -> Option<BlobLocation> {
        if ray[2].is_nan() || ray[2] <= 0.0 || focal_px.is_nan() || focal_px <= 0.0 {
            return None;
        }
        let [r_min, r_max] = params.radius_range_m;
        let mut radius_m = params.radius_prior_m.clamp(r_min, r_max);
        let mut result = None;
        for pass in 0..2 {
            let (depth_m, window) = self.vote(points, ray, radius_m, params)?;
            let centre_m = [
                ray[0] / ray[2] * depth_m,
                ray[1] / ray[2] * depth_m,
                depth_m,
            ];
            let (flatness, asymmetry) = if pass == 1 {
                self.shape(points, window, ray, centre_m, radius_m)
            } else {
                (f64::INFINITY, f64::INFINITY)
            };
            result = Some(BlobLocation {
                centre_m,
                radius_m,
                votes: (window.1 - window.0) as u32,
                samples: self.votes.len() as u32,
                flatness,
                asymmetry,
            });
            let blob_radius_m = blob_radius_px * depth_m / focal_px;
            radius_m = (blob_radius_m / params.blob_over_fruit_radius).clamp(r_min, r_max);
        }
        result
    }

    /// `(flatness, asymmetry)` of the samples of `window` (vote index range): sphere over plane
    /// mean squared residual, and lateral centroid distance from the ray in radii.
    fn shape(
        &mut self,
        points: &[[f32; 3]],
        window: (usize, usize),
        ray: [f64; 3],
        centre_m: [f64; 3],
        radius_m: f64,
    ) -> (f64, f64) {
        self.window.clear();
        let members = self.votes.get(window.0..window.1).unwrap_or(&[]);
        self.window.extend(members.iter().filter_map(|&(_, i)| {
            points
                .get(i as usize)
                .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
        }));
        let (ax, ay) = (ray[0] / ray[2], ray[1] / ray[2]);
        let mut lateral = [0.0, 0.0];
        for p in &self.window {
            lateral[0] += p[0] - ax * p[2];
            lateral[1] += p[1] - ay * p[2];
        }
        let n = self.window.len().max(1) as f64;
        let asymmetry = (lateral[0].hypot(lateral[1]) / n) / radius_m;
        let Some(plane) = plane_rms(&self.window) else {
            return (f64::INFINITY, asymmetry);
        };
        let sphere_ms = self
            .window
            .iter()
            .map(|p| {
                let d = ((p[0] - centre_m[0]).powi(2)
                    + (p[1] - centre_m[1]).powi(2)
                    + (p[2] - centre_m[2]).powi(2))
                .sqrt();
                (d - radius_m).powi(2)
            })
            .sum::<f64>()
            / self.window.len() as f64;
        let flatness = if plane > 0.0 {
            sphere_ms / (plane * plane)
        } else {
            f64::INFINITY
        };
        (flatness, asymmetry)
    }

    /// One vote with radius `radius_m`: `(centre depth, votes in the winning window)`.
    fn vote(
        &mut self,
        points: &[[f32; 3]],
        ray: [f64; 3],
        radius_m: f64,
        params: &BlobLocalizerParams,
    ) -> Option<(f64, (usize, usize))> {
        let (ax, ay) = (ray[0] / ray[2], ray[1] / ray[2]);
        let r_sq = radius_m * radius_m;
        self.votes.clear();
        for (i, p) in points.iter().enumerate() {
            let z = f64::from(p[2]);
            let dx = f64::from(p[0]) - ax * z;
            let dy = f64::from(p[1]) - ay * z;
            let rho_sq = dx * dx + dy * dy;
            if rho_sq < r_sq && z.is_finite() {
                self.votes.push((z + (r_sq - rho_sq).sqrt(), i as u32));
            }
        }
        if self.votes.is_empty() {
            return None;
        }
        self.votes.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let mut middle = self.votes.len() / 2;
        let half = (params.window_sigmas * params.noise.sigma_m(self.votes[middle].0))
            .max(params.min_half_window_m);
        // Densest window [v_i, v_i + 2 half]: two pointers over the sorted votes.
        let (mut best_start, mut best_count) = (0, 0);
        let mut end = 0;
        for start in 0..self.votes.len() {
            end = end.max(start);
            while end < self.votes.len() && self.votes[end].0 <= self.votes[start].0 + 2.0 * half {
                end += 1;
            }
            if end - start > best_count {
                (best_start, best_count) = (start, end - start);
            }
        }
        middle = best_start + best_count / 2;
        Some((self.votes[middle].0, (best_start, best_start + best_count)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> BlobLocalizerParams {
        BlobLocalizerParams {
            radius_range_m: [0.035, 0.05],
            radius_prior_m: 0.0425,
            blob_over_fruit_radius: 1.0,
            window_sigmas: 3.0,
            min_half_window_m: 0.015,
            noise: DepthNoiseModel::TL460,
        }
    }

    /// Front-surface samples of a sphere on a 2 mm lateral grid, plus occluder samples.
    fn sphere_samples(centre: [f64; 3], radius: f64, leaf_depth: Option<f64>) -> Vec<[f32; 3]> {
        let mut points = Vec::new();
        let steps = (radius / 0.002) as i32;
        for i in -steps..=steps {
            for j in -steps..=steps {
                let (dx, dy) = (f64::from(i) * 0.002, f64::from(j) * 0.002);
                let rho_sq = dx * dx + dy * dy;
                if rho_sq >= radius * radius {
                    continue;
                }
                let z = match leaf_depth {
                    // A leaf covers the left 40 % of the fruit.
                    Some(leaf) if dx < -0.2 * radius => leaf,
                    _ => centre[2] - (radius * radius - rho_sq).sqrt(),
                };
                let scale = z / centre[2];
                points.push([
                    ((centre[0] + dx) * scale) as f32,
                    ((centre[1] + dy) * scale) as f32,
                    z as f32,
                ]);
            }
        }
        points
    }

    #[test]
    fn sphere_centre_depth_and_radius_are_recovered() {
        let centre = [0.1, -0.05, 1.5];
        let radius = 0.045;
        let points = sphere_samples(centre, radius, None);
        let ray = [centre[0] / centre[2], centre[1] / centre[2], 1.0];
        let focal = 1600.0;
        let blob_px = focal * radius / centre[2];
        let found = BlobLocalizer::default()
            .locate(&points, ray, blob_px, focal, &params())
            .expect("votes");
        assert!((found.centre_m[2] - 1.5).abs() < 0.004, "{found:?}");
        assert!((found.radius_m - radius).abs() < 0.002, "{found:?}");
        assert!(found.flatness < 0.2, "{found:?}");
        assert!(found.asymmetry < 0.05, "{found:?}");
    }

    #[test]
    fn occluding_leaf_does_not_pull_the_centre_forward() {
        let centre = [0.0, 0.0, 1.2];
        let points = sphere_samples(centre, 0.04, Some(1.1));
        let ray = [0.0, 0.0, 1.0];
        let found = BlobLocalizer::default()
            .locate(&points, ray, 1600.0 * 0.04 / 1.2, 1600.0, &params())
            .expect("votes");
        assert!((found.centre_m[2] - 1.2).abs() < 0.006, "{found:?}");
        assert!(found.votes < found.samples);
        // The leaf hides the left 40 %: the support is the right part.
        assert!(found.asymmetry > 0.2, "{found:?}");
    }

    #[test]
    fn a_flat_leaf_over_the_whole_blob_is_flat() {
        let centre = [0.0, 0.0, 1.2];
        let radius = 0.04;
        // The leaf: all samples at 1.1 m.
        let points: Vec<[f32; 3]> = sphere_samples(centre, radius, None)
            .into_iter()
            .map(|p| {
                let s = 1.1 / f64::from(p[2]);
                [
                    (f64::from(p[0]) * s) as f32,
                    (f64::from(p[1]) * s) as f32,
                    1.1,
                ]
            })
            .collect();
        let found = BlobLocalizer::default()
            .locate(
                &points,
                [0.0, 0.0, 1.0],
                1600.0 * radius / 1.2,
                1600.0,
                &params(),
            )
            .expect("votes");
        assert!(found.flatness > 1.0, "{found:?}");
    }

    #[test]
    fn no_samples_inside_the_silhouette_is_none() {
        let points = [[0.5_f32, 0.5, 1.0]];
        assert!(
            BlobLocalizer::default()
                .locate(&points, [0.0, 0.0, 1.0], 50.0, 1600.0, &params())
                .is_none()
        );
    }
}
