//! Step 5 of the pipeline: estimates of one fruit split by an occluder into several detections
//! merged, best-supported first, and re-estimated from the union of their points.

use super::Perception;
use crate::detector::{DetectionSource, PixelBox};
use crate::estimator::{EstimatorInput, PositionEstimate};
use crate::stats::FrameStats;

/// An estimate waiting for duplicate merging.
#[derive(Debug, Clone, Copy)]
pub(super) struct Pending {
    pub(super) pixel_box: PixelBox,
    pub(super) visible_px: u32,
    pub(super) mask_confidence: f32,
    pub(super) estimate: PositionEstimate,
    pub(super) detections_merged: u32,
    /// Evidence of the (first) detection.
    pub(super) source: DetectionSource,
}

fn squared_distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum()
}

impl Perception {
    /// Greedy merging of estimates of the same fruit, best-supported first.
    pub(super) fn merge_duplicates(&mut self, stats: &mut FrameStats) {
        let mut order: Vec<usize> = (0..self.pending.len()).collect();
        // Colour detections first: an over-exposed blob is only kept where no colour detection
        // already explains its fruit.
        order.sort_by(|&a, &b| {
            let blob = |k: usize| self.pending[k].source == DetectionSource::SaturatedBlob;
            blob(a)
                .cmp(&blob(b))
                .then(
                    self.pending[b]
                        .estimate
                        .points_used
                        .cmp(&self.pending[a].estimate.points_used),
                )
                .then(a.cmp(&b))
        });
        self.accepted.clear();
        for k in order {
            let candidate = self.pending[k];
            let duplicate_of = self.accepted.iter().copied().find(|&a| {
                let kept = &self.pending[a].estimate;
                let c = &candidate.estimate;
                let distance =
                    squared_distance(kept.position_in_camera_m, c.position_in_camera_m).sqrt();
                let floor = self.config.duplicate_min_radius_m;
                distance
                    < self.config.duplicate_distance_radii
                        * (kept.radius_m.max(floor) + c.radius_m.max(floor))
            });
            let Some(a) = duplicate_of else {
                self.accepted.push(k);
                continue;
            };
            stats.duplicates_merged += 1;
            let members = std::mem::take(&mut self.pending_members[k]);
            self.pending_members[a].extend_from_slice(&members);
            self.pending_members[k] = members;
            self.merged_points.clear();
            for &index in &self.pending_members[a] {
                self.merged_points.extend_from_slice(&self.points[index]);
            }
            let merged_box = self.pending[a].pixel_box.union(&candidate.pixel_box);
            let input = EstimatorInput {
                points_in_camera_m: &self.merged_points,
                box_center_ray: self.box_center_ray(&merged_box),
            };
            self.estimator.estimate_all(&input, &mut self.estimates);
            let kept_position = self.pending[a].estimate.position_in_camera_m;
            let reestimate = self.estimates.iter().copied().min_by(|x, y| {
                squared_distance(x.position_in_camera_m, kept_position)
                    .total_cmp(&squared_distance(y.position_in_camera_m, kept_position))
            });
            let kept = &mut self.pending[a];
            kept.pixel_box = merged_box;
            kept.visible_px += candidate.visible_px;
            kept.mask_confidence = kept.mask_confidence.max(candidate.mask_confidence);
            kept.detections_merged += candidate.detections_merged;
            if let Some(estimate) = reestimate
                && self.plausible(&estimate)
            {
                self.pending[a].estimate = estimate;
            }
        }
    }
}
