//! Per-frame ground truth of the apples: where each one is, how much of it the colour camera
//! sees, and which failure conditions of the field evaluation ([dual-arm Table 3]) apply to it.
//!
//! Visibility is measured, not assumed: `visible_px` counts the colour-image pixels the
//! simulator's label render assigns to the apple (leaves, wood, other apples and the image border
//! hide the rest); `unoccluded_px` counts the pixels whose viewing ray hits the apple's sphere with
//! nothing else in the scene, on a sensor extended beyond the image border (so an apple cut by the
//! border is partly hidden). The rays are the undistorted normalised coordinates of the pixel
//! centres, as the renderer uses them, so a fully visible apple has `visible_px ==
//! unoccluded_px`.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_sim::World;
use harvest_sim::render_rgbd::apple_from_label;
use serde::Serialize;

/// A failure condition of the field evaluation, derived per apple from the world's ground truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Condition {
    /// None of the conditions below.
    Clear,
    /// Extra leaves were placed right in front of it (Table 3, "Occlusion").
    Occluded,
    /// Member of a cluster of touching apples (Table 3, "Cluster").
    Clustered,
    /// Sunlight saturates the image around it (Table 3, "Exposure").
    OverExposed,
}

impl Condition {
    pub const ALL: [Self; 4] = [
        Self::Clear,
        Self::Occluded,
        Self::Clustered,
        Self::OverExposed,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Self::Clear => "clear",
            Self::Occluded => "occluded",
            Self::Clustered => "clustered",
            Self::OverExposed => "over_exposed",
        }
    }
}

/// The conditions of one apple; an apple can be in several (then it counts in each), `Clear`
/// only when in none.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AppleConditions {
    pub occluded: bool,
    pub clustered: bool,
    pub over_exposed: bool,
}

impl AppleConditions {
    pub fn has(&self, condition: Condition) -> bool {
        match condition {
            Condition::Clear => !(self.occluded || self.clustered || self.over_exposed),
            Condition::Occluded => self.occluded,
            Condition::Clustered => self.clustered,
            Condition::OverExposed => self.over_exposed,
        }
    }
}

/// Ground truth of one apple in one rendered frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameApple {
    /// True centre, robot frame, metres.
    pub center_in_robot_m: [f64; 3],
    pub radius_m: f64,
    /// Depth (z) of the true centre in the colour camera frame, metres.
    pub depth_m: f64,
    /// Colour-image pixels labelled with this apple.
    pub visible_px: u64,
    /// Pixels the apple would cover with nothing in front of it, image border ignored.
    pub unoccluded_px: u64,
    pub conditions: AppleConditions,
}

impl FrameApple {
    /// Visible fraction of the apple's silhouette, in [0, 1] (0 when it is behind the camera).
    pub fn visible_fraction(&self) -> f64 {
        if self.unoccluded_px == 0 {
            0.0
        } else {
            (self.visible_px as f64 / self.unoccluded_px as f64).min(1.0)
        }
    }
}

/// Measures [`FrameApple`]s from a world and its label render.
#[derive(Debug)]
pub struct TruthMeter {
    intrinsics: CameraIntrinsics,
    color_from_robot: RigidTransform,
    width: usize,
    height: usize,
    /// Undistorted normalised coordinates of every colour pixel centre, row-major.
    rays: Vec<[f32; 2]>,
}

impl TruthMeter {
    /// A meter for the colour camera `intrinsics` at pose `robot_from_color`.
    pub fn new(intrinsics: CameraIntrinsics, robot_from_color: RigidTransform) -> Self {
        let width = intrinsics.width_px as usize;
        let height = intrinsics.height_px as usize;
        let rays = intrinsics.pixel_ray_table();
        Self {
            intrinsics,
            color_from_robot: robot_from_color.inverse(),
            width,
            height,
            rays,
        }
    }

    pub fn width_px(&self) -> usize {
        self.width
    }

    /// Pixels of the colour image (the length of a label image).
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Ground truth of every apple of `world`, in [`harvest_sim::AppleId`] order, from the label
    /// render `labels` of the same world.
    pub fn measure(&self, world: &World, labels: &[u32], out: &mut Vec<FrameApple>) {
        out.clear();
        for truth in world.ground_truth().apples {
            let in_color = self.color_from_robot.apply(truth.center_in_robot_m);
            out.push(FrameApple {
                center_in_robot_m: truth.center_in_robot_m,
                radius_m: truth.radius_m,
                depth_m: in_color[2],
                visible_px: 0,
                unoccluded_px: self.unoccluded_px(in_color, truth.radius_m),
                conditions: AppleConditions {
                    occluded: truth.heavily_occluded,
                    clustered: truth.cluster.is_some(),
                    over_exposed: truth.overexposed,
                },
            });
        }
        for &label in labels {
            if let Some(id) = apple_from_label(label)
                && let Some(apple) = out.get_mut(id.0 as usize)
            {
                apple.visible_px += 1;
            }
        }
    }

    /// Pixels whose ray hits the sphere `center_in_color_m`, `radius_m` (colour camera frame).
    fn unoccluded_px(&self, center_in_color_m: [f64; 3], radius_m: f64) -> u64 {
        let [cx, cy, cz] = center_in_color_m;
        let r = radius_m;
        // Nothing within 5 cm of the camera is drawn by the renderer either.
        let nearest_m = cz - r;
        if nearest_m.is_nan() || nearest_m <= 0.05 {
            return 0;
        }
        let c_sq_minus_r_sq = cx * cx + cy * cy + cz * cz - r * r;
        // Exact tangent bounds of the silhouette in x/z and y/z, pushed through the distortion.
        let extent = |lateral: f64| {
            let denominator = cz * cz - r * r;
            let root = r * (lateral * lateral + denominator).sqrt();
            (
                (lateral * cz - root) / denominator,
                (lateral * cz + root) / denominator,
            )
        };
        let (x0, x1) = extent(cx);
        let (y0, y1) = extent(cy);
        let (mut u_min, mut u_max, mut v_min, mut v_max) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        const SAMPLES: usize = 8;
        for k in 0..=SAMPLES {
            let f = k as f64 / SAMPLES as f64;
            let (x, y) = (x0 + (x1 - x0) * f, y0 + (y1 - y0) * f);
            for (xn, yn) in [(x, y0), (x, y1), (x0, y), (x1, y)] {
                let (u, v) = self.intrinsics.denormalize(xn, yn);
                u_min = u_min.min(u);
                u_max = u_max.max(u);
                v_min = v_min.min(v);
                v_max = v_max.max(v);
            }
        }
        if !(u_min.is_finite() && u_max.is_finite() && v_min.is_finite() && v_max.is_finite()) {
            return 0;
        }
        let mut count = 0;
        for v in (v_min.floor() as i64 - 2)..=(v_max.ceil() as i64 + 2) {
            for u in (u_min.floor() as i64 - 2)..=(u_max.ceil() as i64 + 2) {
                let (x, y) = self.ray(u, v);
                let b = x * cx + y * cy + cz;
                let dd = x * x + y * y + 1.0;
                if b > 0.0 && b * b - dd * c_sq_minus_r_sq >= 0.0 {
                    count += 1;
                }
            }
        }
        count
    }

    /// Undistorted normalised coordinates of pixel `(u, v)` (inside or outside the image).
    fn ray(&self, u: i64, v: i64) -> (f64, f64) {
        if (0..self.width as i64).contains(&u) && (0..self.height as i64).contains(&v) {
            let [x, y] = self.rays[v as usize * self.width + u as usize];
            (f64::from(x), f64::from(y))
        } else {
            self.intrinsics.normalize(u as f64, v as f64)
        }
    }
}

/// Adds, for every apple, its labelled pixels inside the box `[u_min, u_max) x [v_min, v_max)`
/// of the row-major label image `labels` (`width_px` wide) to `row` (indexed by apple id).
pub fn count_box_overlap(labels: &[u32], width_px: usize, box_px: [u32; 4], row: &mut [u64]) {
    let [u_min, v_min, box_width, box_height] = box_px.map(|x| x as usize);
    if width_px == 0 {
        return;
    }
    let height_px = labels.len() / width_px;
    let u_max = (u_min + box_width).min(width_px);
    let v_max = (v_min + box_height).min(height_px);
    for v in v_min.min(v_max)..v_max {
        for &label in &labels[v * width_px + u_min.min(u_max)..v * width_px + u_max] {
            if let Some(id) = apple_from_label(label)
                && let Some(count) = row.get_mut(id.0 as usize)
            {
                *count += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::render_rgbd::label;

    #[test]
    fn conditions_clear_only_without_any() {
        let clear = AppleConditions::default();
        assert!(clear.has(Condition::Clear));
        assert!(!clear.has(Condition::Occluded));
        let both = AppleConditions {
            occluded: true,
            clustered: true,
            over_exposed: false,
        };
        assert!(!both.has(Condition::Clear));
        assert!(both.has(Condition::Occluded) && both.has(Condition::Clustered));
        assert!(!both.has(Condition::OverExposed));
    }

    #[test]
    fn box_overlap_counts_labels_inside_the_box() {
        // 4x3 image: apple 0 in the left column, apple 1 at (2, 1) and (3, 2), a leaf elsewhere.
        let a0 = label::APPLE_BASE;
        let a1 = label::APPLE_BASE + 1;
        let leaf = label::LEAF;
        #[rustfmt::skip]
        let labels = [
            a0, leaf, leaf, leaf,
            a0, leaf, a1, leaf,
            a0, leaf, leaf, a1,
        ];
        let mut row = [0u64; 2];
        count_box_overlap(&labels, 4, [0, 1, 3, 2], &mut row);
        assert_eq!(row, [2, 1]);
        let mut row = [0u64; 2];
        // A box reaching past the border is clipped.
        count_box_overlap(&labels, 4, [2, 0, 10, 10], &mut row);
        assert_eq!(row, [0, 2]);
    }

    #[test]
    fn centred_apple_area_matches_the_pinhole_disc() {
        let intrinsics = CameraIntrinsics::from_horizontal_fov(640, 480, 60.0);
        let meter = TruthMeter::new(intrinsics, RigidTransform::IDENTITY);
        // A sphere of radius r at distance d on the axis: image radius f r / sqrt(d^2 - r^2).
        let (r, d) = (0.04, 1.0);
        let area = meter.unoccluded_px([0.0, 0.0, d], r) as f64;
        let radius_px = intrinsics.fx_px * r / (d * d - r * r).sqrt();
        let expected = std::f64::consts::PI * radius_px * radius_px;
        assert!((area / expected - 1.0).abs() < 0.02, "{area} vs {expected}");
        // Centred on the left border: the extended sensor still counts all of it. Off axis by
        // theta the image of a small sphere grows to `pi (f r / d)^2 / cos(theta)` (solid angle
        // `pi r^2 cos^2(theta) / d^2` times the image area per solid angle `f^2 / cos^3(theta)`).
        let x_n = (intrinsics.cx_px + 0.5) / intrinsics.fx_px;
        let area = meter.unoccluded_px([-x_n * d, 0.0, d], r) as f64;
        let cos_theta = 1.0 / (1.0 + x_n * x_n).sqrt();
        let expected = std::f64::consts::PI * (intrinsics.fx_px * r / d).powi(2) / cos_theta;
        assert!((area / expected - 1.0).abs() < 0.02, "{area} vs {expected}");
        assert_eq!(meter.unoccluded_px([0.0, 0.0, -1.0], r), 0);
    }
}
