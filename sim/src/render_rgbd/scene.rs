//! The world's objects (apples, leaves, branches, over-exposure highlights) expressed as
//! primitives in one camera's frame, each with the pixel box it may cover.

use super::camera::{NEAR_M, PixelBox, RasterCamera};
use super::label;
use super::{V3, to_f32};
use crate::orchard::{AppleState, World};

/// Branches are drawn in pieces of at most this length, so a long diagonal branch gets several
/// small pixel boxes instead of one large one (metres).
pub(super) const CYLINDER_SEGMENT_M: f64 = 0.1;
/// Corners of the polygon bounding a leaf's ellipse.
pub(super) const LEAF_HULL_CORNERS: usize = 12;
/// Vertex radius of a regular 12-gon circumscribing the unit circle: `1 / cos(pi / 12)`.
pub(super) const LEAF_HULL_SCALE: f64 = 1.035_276_180_410_083;

/// An apple, in the camera frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct SpherePrim {
    pub(super) center: V3,
    pub(super) inv_radius: f32,
    /// `|c|^2 - r^2`.
    pub(super) c_sq_minus_r_sq: f32,
    pub(super) label: u32,
    pub(super) blush: V3,
    pub(super) ground: V3,
    pub(super) blush_axis: V3,
    /// Blush where `n . axis > 1 - 2 f` (a cap of area fraction `f`).
    pub(super) blush_cos: f32,
    /// Specular highlight of an over-exposed apple; `None` for a normally lit one.
    pub(super) glare: Option<GlareDisc>,
    pub(super) area: PixelBox,
}

/// A leaf, in the camera frame.
///
/// For a ray `d = (x, y, 1)` the plane hit is at `t = (n . c) / (n . d)`, and the hit's in-plane
/// coordinates (over the half axes) are `along = A(d) / D(d)`, `across = B(d) / D(d)` with
/// `D = n . d`, `A = (n . c)(u . d) - (c . u) D`, `B = (n . c)(v . d) - (c . v) D`: all three are
/// linear in `d`, so the inside test `A^2 + B^2 <= D^2` needs no division. The normal is
/// oriented so that `n . c > 0` (pointing away from the camera); then a hit lies in front of the
/// camera iff `D > 0` and is nearer than `z` iff `n . c < z D`: the division `t = n . c / D` is
/// only done for pixels the leaf wins.
#[derive(Debug, Clone, Copy)]
pub(super) struct DiscPrim {
    /// Unit normal pointing away from the camera.
    pub(super) normal: V3,
    pub(super) n_dot_c: f32,
    /// Coefficients of `A`.
    pub(super) along: V3,
    /// Coefficients of `B`.
    pub(super) across: V3,
    pub(super) rgb: V3,
    pub(super) area: PixelBox,
    pub(super) depth_key: f32,
}

/// A branch, in the camera frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct CylinderPrim {
    pub(super) start: V3,
    pub(super) axis: V3,
    pub(super) length: f32,
    pub(super) inv_radius: f32,
    /// Component of `-start` perpendicular to the axis.
    pub(super) w_perp: V3,
    /// `|w_perp|^2 - r^2`.
    pub(super) w_perp_sq_minus_r_sq: f32,
    pub(super) start_dot_axis: f32,
    pub(super) rgb: V3,
    pub(super) area: PixelBox,
}

/// The highlight disc of an over-exposed apple, in normalised image coordinates.
#[derive(Debug, Clone, Copy)]
pub(super) struct GlareDisc {
    pub(super) center: [f32; 2],
    pub(super) inv_radius_sq: f32,
}

/// An over-exposed apple's highlight disc with its pixel box and the apple's label: only pixels
/// the apple itself wins are affected.
#[derive(Debug, Clone, Copy)]
pub(super) struct GlarePrim {
    pub(super) disc: GlareDisc,
    pub(super) label: u32,
    pub(super) area: PixelBox,
}

/// The world's objects in one camera's frame, rebuilt each frame into reused vectors.
#[derive(Debug, Default)]
pub(super) struct Scene {
    pub(super) spheres: Vec<SpherePrim>,
    pub(super) discs: Vec<DiscPrim>,
    pub(super) cylinders: Vec<CylinderPrim>,
    pub(super) glare: Vec<GlarePrim>,
}

impl Scene {
    pub(super) fn prepare(&mut self, world: &World, camera: &RasterCamera, patch_scale: f64) {
        self.spheres.clear();
        self.discs.clear();
        self.cylinders.clear();
        self.glare.clear();
        let pose = &camera.camera_from_robot;
        for apple in world.apples() {
            if !matches!(
                apple.state,
                AppleState::OnTree | AppleState::Attached { .. }
            ) {
                continue;
            }
            let c = pose.apply(apple.center_in_robot_m);
            let r = apple.radius_m;
            if c[2] - r <= NEAR_M {
                continue;
            }
            // Exact tangent bounds of the sphere's silhouette in x/z and y/z.
            let extent = |lateral: f64| {
                let denominator = c[2] * c[2] - r * r;
                let root = r * (lateral * lateral + denominator).sqrt();
                (
                    (lateral * c[2] - root) / denominator,
                    (lateral * c[2] + root) / denominator,
                )
            };
            let (x0, x1) = extent(c[0]);
            let (y0, y1) = extent(c[1]);
            let Some(area) = camera.pixel_box(x0, x1, y0, y1) else {
                continue;
            };
            let center = to_f32(c);
            let label = label::APPLE_BASE + apple.id.0;
            let mut glare = None;
            if apple.overexposed && patch_scale > 0.0 {
                let radius = patch_scale * r / c[2];
                let (cx, cy) = (c[0] / c[2], c[1] / c[2]);
                let disc = GlareDisc {
                    center: [cx as f32, cy as f32],
                    inv_radius_sq: (1.0 / (radius * radius)) as f32,
                };
                glare = Some(disc);
                if let Some(area) =
                    camera.pixel_box(cx - radius, cx + radius, cy - radius, cy + radius)
                {
                    self.glare.push(GlarePrim { disc, label, area });
                }
            }
            self.spheres.push(SpherePrim {
                center,
                inv_radius: (1.0 / r) as f32,
                c_sq_minus_r_sq: (c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - r * r) as f32,
                label,
                blush: apple.blush_rgb,
                ground: apple.ground_rgb,
                blush_axis: to_f32(pose.rotate(apple.blush_axis_in_robot)),
                blush_cos: (1.0 - 2.0 * apple.blush_fraction) as f32,
                glare,
                area,
            });
        }
        for leaf in world.leaves() {
            let c = pose.apply(leaf.center_in_robot_m);
            let n = pose.rotate(leaf.normal_in_robot);
            let n = if n[0] * c[0] + n[1] * c[1] + n[2] * c[2] < 0.0 {
                n.map(|k| -k)
            } else {
                n
            };
            let major = pose.rotate(leaf.major_axis_in_robot);
            let minor = [
                n[1] * major[2] - n[2] * major[1],
                n[2] * major[0] - n[0] * major[2],
                n[0] * major[1] - n[1] * major[0],
            ];
            let (a, b) = (leaf.half_length_m, leaf.half_width_m);
            // The leaf's image of a regular polygon circumscribing the unit circle contains the
            // ellipse, and is much tighter than its bounding rectangle when the leaf is rotated.
            let corners: [[f64; 3]; LEAF_HULL_CORNERS] = std::array::from_fn(|i| {
                let (sin, cos) =
                    (std::f64::consts::TAU * i as f64 / LEAF_HULL_CORNERS as f64).sin_cos();
                let (su, sv) = (cos * LEAF_HULL_SCALE, sin * LEAF_HULL_SCALE);
                std::array::from_fn(|k| c[k] + su * a * major[k] + sv * b * minor[k])
            });
            let Some(area) = camera.hull_box(&corners) else {
                continue;
            };
            let n_dot_c = n[0] * c[0] + n[1] * c[1] + n[2] * c[2];
            let linear = |axis: [f64; 3], half: f64| {
                let c_dot_axis = (c[0] * axis[0] + c[1] * axis[1] + c[2] * axis[2]) / half;
                to_f32(std::array::from_fn(|k| {
                    n_dot_c * axis[k] / half - c_dot_axis * n[k]
                }))
            };
            self.discs.push(DiscPrim {
                normal: to_f32(n),
                n_dot_c: n_dot_c as f32,
                along: linear(major, a),
                across: linear(minor, b),
                rgb: leaf.rgb,
                area,
                depth_key: c[2] as f32,
            });
        }
        // Front to back: nearer leaves claim their pixels first, so fewer get shaded twice.
        self.discs
            .sort_unstable_by(|a, b| a.depth_key.total_cmp(&b.depth_key));
        for branch in world.branches() {
            let p0 = pose.apply(branch.start_in_robot_m);
            let p1 = pose.apply(branch.end_in_robot_m);
            let delta = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
            let length = (delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]).sqrt();
            if length < 1e-9 {
                continue;
            }
            let axis = delta.map(|d| d / length);
            let segments = (length / CYLINDER_SEGMENT_M).ceil().max(1.0);
            let segment_length = length / segments;
            for segment in 0..segments as usize {
                let p0: [f64; 3] =
                    std::array::from_fn(|k| p0[k] + axis[k] * segment_length * segment as f64);
                self.push_cylinder(
                    camera,
                    p0,
                    axis,
                    segment_length,
                    branch.radius_m,
                    branch.rgb,
                );
            }
        }
    }

    /// Adds one straight cylinder piece (camera frame) if it is in view.
    fn push_cylinder(
        &mut self,
        camera: &RasterCamera,
        p0: [f64; 3],
        axis: [f64; 3],
        length: f64,
        r: f64,
        rgb: V3,
    ) {
        let p1: [f64; 3] = std::array::from_fn(|k| p0[k] + axis[k] * length);
        {
            let helper = if axis[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let e1 = crate::scenario::normalized(crate::scenario::cross(axis, helper))
                .unwrap_or([0.0, 0.0, 1.0]);
            let e2 = crate::scenario::cross(axis, e1);
            let mut corners = [[0.0; 3]; 8];
            for (index, corner) in corners.iter_mut().enumerate() {
                let end = if index & 1 == 0 { p0 } else { p1 };
                let s1 = if index & 2 == 0 { r } else { -r };
                let s2 = if index & 4 == 0 { r } else { -r };
                *corner = std::array::from_fn(|k| end[k] + s1 * e1[k] + s2 * e2[k]);
            }
            let Some(area) = camera.hull_box(&corners) else {
                return;
            };
            let w = p0.map(|p| -p);
            let w_dot_a = w[0] * axis[0] + w[1] * axis[1] + w[2] * axis[2];
            let w_perp: [f64; 3] = std::array::from_fn(|k| w[k] - w_dot_a * axis[k]);
            let w_perp_sq = w_perp[0] * w_perp[0] + w_perp[1] * w_perp[1] + w_perp[2] * w_perp[2];
            self.cylinders.push(CylinderPrim {
                start: to_f32(p0),
                axis: to_f32(axis),
                length: length as f32,
                inv_radius: (1.0 / r) as f32,
                w_perp: to_f32(w_perp),
                w_perp_sq_minus_r_sq: (w_perp_sq - r * r) as f32,
                start_dot_axis: -w_dot_a as f32,
                rgb,
                area,
            });
        }
    }
}

/// Glare weight at a ray: `1 - (d / R)^2` inside the disc, else <= 0.
#[inline(always)]
pub(super) fn glare_weight(glare: &GlareDisc, ray: [f32; 2]) -> f32 {
    let dx = ray[0] - glare.center[0];
    let dy = ray[1] - glare.center[1];
    1.0 - (dx * dx + dy * dy) * glare.inv_radius_sq
}
