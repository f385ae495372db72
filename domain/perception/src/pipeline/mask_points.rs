//! Step 3 of the pipeline: the active detections' masks painted into a label image, and every
//! registered depth sample assigned to the detection under it (the mask points).

use tracing::debug;

use super::Perception;
use crate::frame::DepthView;
use crate::stats::FrameStats;

/// Side of a label-image cell in colour pixels.
pub(super) const LABEL_CELL_PX: u32 = 2;

impl Perception {
    /// Paints the active detections' masks into the label image, least confident first.
    pub(super) fn paint_labels(&mut self) {
        self.label_map.fill(0);
        let detections = &self.detections;
        self.active.sort_by(|&a, &b| {
            detections[a]
                .confidence
                .total_cmp(&detections[b].confidence)
                .then(a.cmp(&b))
        });
        let cell = LABEL_CELL_PX;
        for &index in &self.active {
            let detection = &self.detections[index];
            let b = detection.pixel_box;
            let x_end = (b.u_max_px.div_ceil(cell) as usize).min(self.label_width);
            let y_end = (b.v_max_px.div_ceil(cell) as usize).min(self.label_height);
            let label = (index + 1) as u16;
            for y in (b.v_min_px / cell) as usize..y_end {
                let v_px = y as u32 * cell + cell / 2;
                let row = y * self.label_width;
                for x in (b.u_min_px / cell) as usize..x_end {
                    if detection.mask.contains_px(x as u32 * cell + cell / 2, v_px) {
                        self.label_map[row + x] = label;
                    }
                }
            }
        }
    }

    /// Registers the depth frame and appends every sample to the detection under it.
    pub(super) fn collect_points(&mut self, depth: &DepthView<'_>, stats: &mut FrameStats) {
        if self.points.len() < self.detections.len() {
            self.points.resize_with(self.detections.len(), Vec::new);
        }
        for points in &mut self.points {
            points.clear();
        }
        if self.active.is_empty() {
            // Still count the depth quality of the frame.
            let counts = self.registration.register(depth, |_| {});
            if let Ok(counts) = counts {
                stats.depth_registered_px = counts.registered;
                stats.depth_zero_px = counts.zero;
                stats.depth_out_of_range_px = counts.out_of_range;
                stats.depth_outside_color_px = counts.outside_color;
            }
            return;
        }
        let label_map = &self.label_map;
        let label_width = self.label_width;
        let label_height = self.label_height;
        let points = &mut self.points;
        let cell = f64::from(LABEL_CELL_PX);
        let result = self.registration.register(depth, |sample| {
            let x = ((sample.u_px + 0.5) / cell) as usize;
            let y = ((sample.v_px + 0.5) / cell) as usize;
            if x >= label_width || y >= label_height {
                return;
            }
            let label = label_map[y * label_width + x];
            if label == 0 {
                return;
            }
            if let Some(list) = points.get_mut(usize::from(label) - 1) {
                let p = sample.point_in_camera_m;
                list.push([p[0] as f32, p[1] as f32, p[2] as f32]);
            }
        });
        match result {
            Ok(counts) => {
                stats.depth_registered_px = counts.registered;
                stats.depth_zero_px = counts.zero;
                stats.depth_out_of_range_px = counts.out_of_range;
                stats.depth_outside_color_px = counts.outside_color;
            }
            Err(error) => {
                // Unreachable after the size check in `run`; kept so a bad frame never panics.
                debug!(%error, "depth registration failed");
                stats.rejection = Some(error);
            }
        }
    }
}
