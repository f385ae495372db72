//! Step 4 of the pipeline: each active detection's mask points and box-centre ray turned into
//! positions by the estimator (or, for an over-exposed blob, by the blob localizer), checked
//! for plausibility and depth agreement.

use tracing::trace;

use super::merge::Pending;
use super::{Perception, PerceptionConfig};
use crate::blob_localization::{BlobLocalizer, BlobLocalizerParams};
use crate::detector::{DetectionSource, PixelBox};
use crate::estimate_checks::{blob_radius_px, depth_agrees, median_depth_m};
use crate::estimator::{EstimatorInput, EstimatorKind, PositionEstimate};
use crate::stats::FrameStats;

/// Blob radius over fruit radius: the simulator's and the sun's saturated disc slightly exceeds
/// the fruit.
const BLOB_OVER_FRUIT_RADIUS: f64 = 1.02;
/// Half width of a blob's depth-vote window, in nominal depth-noise sigmas.
const BLOB_VOTE_WINDOW_SIGMAS: f64 = 3.0;
/// Lower bound of the half width of a blob's depth-vote window, metres.
const BLOB_VOTE_MIN_HALF_WINDOW_M: f64 = 0.015;

impl Perception {
    /// Ray `(x/z, y/z, 1)` through a box centre in the colour camera.
    pub(super) fn box_center_ray(&self, pixel_box: &PixelBox) -> [f64; 3] {
        let (u, v) = pixel_box.center_px();
        let (x, y) = self.cameras.color.normalize(u, v);
        [x, y, 1.0]
    }

    pub(super) fn plausible(&self, estimate: &PositionEstimate) -> bool {
        let p = estimate.position_in_camera_m;
        let min_m = f64::from(self.config.depth_range.min_mm) * 1e-3;
        let max_m = f64::from(self.config.depth_range.max_mm) * 1e-3;
        p.iter().all(|v| v.is_finite())
            && estimate.radius_m.is_finite()
            && estimate.confidence.is_finite()
            && p[2] >= min_m
            && p[2] <= max_m
    }

    /// Box of a sphere's image in the colour camera, clipped to the image.
    fn sphere_box(&self, estimate: &PositionEstimate) -> Option<PixelBox> {
        let color = &self.cameras.color;
        let centre = estimate.position_in_camera_m;
        let (u, v) = color.project(centre)?;
        let depth = centre[2] - estimate.radius_m;
        if depth <= 0.0 {
            return None;
        }
        let half_u = color.fx_px * estimate.radius_m / depth;
        let half_v = color.fy_px * estimate.radius_m / depth;
        let clip = |x: f64, max: u32| x.clamp(0.0, f64::from(max)) as u32;
        let pixel_box = PixelBox {
            u_min_px: clip((u - half_u).floor(), color.width_px),
            v_min_px: clip((v - half_v).floor(), color.height_px),
            u_max_px: clip((u + half_u).ceil() + 1.0, color.width_px),
            v_max_px: clip((v + half_v).ceil() + 1.0, color.height_px),
        };
        (pixel_box.width_px() > 0 && pixel_box.height_px() > 0).then_some(pixel_box)
    }

    /// Estimates per active detection with enough points (several when the estimator finds
    /// several fruit in one mask).
    pub(super) fn estimate_detections(&mut self, stats: &mut FrameStats) {
        self.pending.clear();
        for members in &mut self.pending_members {
            members.clear();
        }
        let mut estimates = std::mem::take(&mut self.estimates);
        for i in 0..self.active.len() {
            let index = self.active[i];
            let points = &self.points[index];
            let detection = &self.detections[index];
            let blob = detection.source == DetectionSource::SaturatedBlob;
            if points.len() < self.config.min_points_per_apple as usize {
                if blob {
                    // White without depth: sky, not a fruit.
                    stats.saturated_blobs_rejected += 1;
                } else {
                    stats.detections_without_depth += 1;
                }
                continue;
            }
            if blob
                && self
                    .blob_check
                    .depth_coverage(points.len(), detection.visible_px)
                    < self.blob_check.min_depth_coverage
            {
                stats.saturated_blobs_rejected += 1;
                continue;
            }
            let Some(median_m) = median_depth_m(points, &mut self.depth_scratch) else {
                stats.detections_without_depth += 1;
                continue;
            };
            let box_center_ray = self.box_center_ray(&detection.pixel_box);
            let blob_radius_px = blob_radius_px(
                detection.visible_px,
                detection.pixel_box.width_px(),
                detection.pixel_box.height_px(),
            );
            if blob && self.estimator.kind() != EstimatorKind::ClusterDepth {
                estimates.clear();
                estimates.extend(blob_estimate(
                    &mut self.blob_localizer,
                    &self.config,
                    self.blob_check.color_focal_px,
                    points,
                    box_center_ray,
                    blob_radius_px,
                ));
            } else {
                let input = EstimatorInput {
                    points_in_camera_m: points,
                    box_center_ray,
                };
                self.estimator.estimate_all(&input, &mut estimates);
            }
            if estimates.is_empty() {
                if blob {
                    stats.saturated_blobs_rejected += 1;
                } else {
                    stats.estimates_failed += 1;
                }
                continue;
            }
            if blob {
                // Only the best-supported fruit of a blob; its size must be an apple's.
                estimates.truncate(1);
                if !self.blob_check.confirms(
                    points.len(),
                    detection.visible_px,
                    blob_radius_px,
                    &estimates[0],
                ) {
                    stats.saturated_blobs_rejected += 1;
                    continue;
                }
                stats.saturated_blobs_confirmed += 1;
            }
            let several = estimates.len() > 1;
            let support: f64 = estimates.iter().map(|e| f64::from(e.points_used)).sum();
            for (rank, estimate) in estimates.iter().enumerate() {
                if !self.plausible(estimate) {
                    stats.estimates_rejected += 1;
                    continue;
                }
                // Further fruit lie behind the first by construction; the first is checked.
                if rank == 0
                    && !depth_agrees(
                        estimate,
                        median_m,
                        &self.config.depth_noise(),
                        self.config.depth_agreement_sigmas,
                    )
                {
                    stats.estimates_inconsistent += 1;
                    continue;
                }
                let (pixel_box, visible_px) = if several {
                    let share = f64::from(estimate.points_used) / support.max(1.0);
                    (
                        self.sphere_box(estimate).unwrap_or(detection.pixel_box),
                        (f64::from(detection.visible_px) * share).round() as u32,
                    )
                } else {
                    (detection.pixel_box, detection.visible_px)
                };

                let k = self.pending.len();
                self.pending.push(Pending {
                    pixel_box,
                    visible_px,
                    mask_confidence: detection.confidence,
                    estimate: *estimate,
                    detections_merged: 1,
                    source: detection.source,
                });
                if self.pending_members.len() <= k {
                    self.pending_members.push(Vec::new());
                }
                self.pending_members[k].push(index);
            }
            stats.extra_fruit_in_detections += estimates.len().saturating_sub(1) as u32;
        }
        self.estimates = estimates;
    }
}

/// Position of a depth-confirmed over-exposed blob ([`BlobLocalizer`]).
fn blob_estimate(
    localizer: &mut BlobLocalizer,
    config: &PerceptionConfig,
    color_focal_px: f64,
    points: &[[f32; 3]],
    ray: [f64; 3],
    blob_radius_px: f64,
) -> Option<PositionEstimate> {
    let fit = &config.estimator.sphere_fit;
    let params = BlobLocalizerParams {
        radius_range_m: [fit.radius_min_m, fit.radius_max_m],
        radius_prior_m: fit.radius_prior_m,
        blob_over_fruit_radius: BLOB_OVER_FRUIT_RADIUS,
        window_sigmas: BLOB_VOTE_WINDOW_SIGMAS,
        min_half_window_m: BLOB_VOTE_MIN_HALF_WINDOW_M,
        noise: config.depth_noise(),
    };
    let location = localizer.locate(points, ray, blob_radius_px, color_focal_px, &params)?;
    trace!(
        flatness = location.flatness,
        asymmetry = location.asymmetry,
        votes = location.votes,
        samples = location.samples,
        depth_m = location.centre_m[2],
        "over-exposed blob located"
    );
    let curved = location.flatness <= config.saturated_blob_max_flatness;
    let centred = location.asymmetry <= config.saturated_blob_max_asymmetry;
    if !(curved && centred) {
        return None;
    }
    Some(PositionEstimate {
        position_in_camera_m: location.centre_m,
        radius_m: location.radius_m,
        confidence: config.saturated_blob_position_confidence,
        points_used: location.votes,
        fallback: false,
    })
}
