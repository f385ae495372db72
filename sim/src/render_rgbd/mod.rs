//! Rendering of the ToF camera's frames (Percipio TL460-S1-E1, paper 003 section 2.1) from the
//! simulated world: RGB 1920x1080 RGB8 and depth 640x480 u16 millimetres (0 = no return).
//!
//! Method: per-object rasterisation with a per-pixel z-buffer. Every object's silhouette is
//! bounded in undistorted normalised image coordinates, the bound is pushed through the lens
//! distortion to a pixel box, and only the pixels in that box are intersected with the object.
//! Each pixel's viewing ray `(x_n, y_n, 1)` is precomputed once per camera by undistorting the
//! pixel centre with [`CameraIntrinsics::normalize`], so distortion costs nothing per frame. With
//! rays of unit z, the ray parameter of a hit is the hit's depth `z` directly.
//!
//! Objects are drawn band by band (16 image rows at a time, each object clipped to the band) so
//! the band's rays, depths and colours stay in cache while the two to three layers of leaves,
//! apples and branches covering it are drawn. The backdrop (next tree row and ground as planes,
//! sky above with no depth return) never moves: it is rendered once per camera and copied in at
//! the start of each frame. `measure_render_rate` in [`crate::render_rate`] reports the speed.
//!
//! Shading: Lambert diffuse plus a Blinn-Phong highlight on apples under the scenario's sun, an
//! ambient sky term, two-sided translucent leaves.
//!
//! Depth error: the TL460 specifies +/-(4 mm + 0.25 % of depth). It is taken here as one standard
//! deviation of zero-mean Gaussian noise, `sigma = 4 mm + 0.0025 z`, independent per pixel and per
//! frame (seeded by world seed and frame number), outside 0.3-9.5 m the pixel reads 0.
//!
//! Over-exposure (Table 3, "Exposure"): an apple flagged over-exposed reflects direct sunlight
//! into the lens (a specular, saturated highlight on its waxy skin). The highlight is a disc of
//! `overexposed_patch_scale` apple radii around the apple's projected centre, but only the apple's
//! own visible pixels are affected: leaves and branches in front of it keep their own colour and
//! depth. On those pixels the RGB saturates towards white; in depth the noise grows up to
//! `overexposed_depth_noise_gain` and pixels drop out with up to
//! `overexposed_dropout_probability`, both tapering to the disc's edge.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

use crate::orchard::{AppleId, AppleState, World};
use crate::scenario::{BackgroundConfig, CameraConfig, CameraPoseError, LightingConfig};

/// Per-pixel labels written by [`RgbdRenderer::render_labels`].
pub mod label {
    /// Sky: no surface within range.
    pub const SKY: u32 = 0;
    /// The next tree row behind the canopy.
    pub const NEXT_ROW: u32 = 1;
    pub const GROUND: u32 = 2;
    pub const LEAF: u32 = 3;
    /// Trunks, branches, uprights, cordons.
    pub const WOOD: u32 = 4;
    /// Apple `id` is labelled `APPLE_BASE + id`.
    pub const APPLE_BASE: u32 = 16;
}

/// The apple a label belongs to, if it is an apple label.
pub fn apple_from_label(label: u32) -> Option<AppleId> {
    label.checked_sub(label::APPLE_BASE).map(AppleId)
}

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The caller's buffer does not have the frame's size.
    #[error("{buffer} buffer holds {actual} elements; a {width}x{height} frame needs {expected}")]
    BufferSize {
        buffer: &'static str,
        expected: usize,
        actual: usize,
        width: u32,
        height: u32,
    },
    /// The camera pose in the scenario is degenerate.
    #[error("camera pose: {0}")]
    CameraPose(#[from] CameraPoseError),
}

type V3 = [f32; 3];

/// Objects closer to the camera than this (z, metres) are not drawn.
const NEAR_M: f64 = 0.05;
/// Branches are drawn in pieces of at most this length, so a long diagonal branch gets several
/// small pixel boxes instead of one large one (metres).
const CYLINDER_SEGMENT_M: f64 = 0.1;
/// Corners of the polygon bounding a leaf's ellipse.
const LEAF_HULL_CORNERS: usize = 12;
/// Vertex radius of a regular 12-gon circumscribing the unit circle: `1 / cos(pi / 12)`.
const LEAF_HULL_SCALE: f64 = 1.035_276_180_410_083;
/// Decorrelates the depth-noise stream from the world's other random streams.
const DEPTH_NOISE_STREAM: u64 = 0xd1b5_4a32_d192_ed03;

#[inline(always)]
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn to_f32(v: [f64; 3]) -> V3 {
    [v[0] as f32, v[1] as f32, v[2] as f32]
}

/// Inclusive pixel rectangle.
#[derive(Debug, Clone, Copy)]
struct PixelBox {
    u0: usize,
    u1: usize,
    v0: usize,
    v1: usize,
}

/// One sensor: intrinsics, pose, per-pixel rays and z-buffer.
#[derive(Debug)]
struct RasterCamera {
    intrinsics: CameraIntrinsics,
    camera_from_robot: RigidTransform,
    robot_from_camera: RigidTransform,
    width: usize,
    height: usize,
    /// Undistorted normalised coordinates `(x/z, y/z)` of every pixel centre, row-major.
    rays: Vec<[f32; 2]>,
    /// Depth (z, metres) of the nearest surface so far; infinity = nothing.
    z_m: Vec<f32>,
    /// The static backdrop as this camera sees it.
    backdrop: BackdropCache,
}

/// What the backdrop's appearance depends on besides the (fixed) camera pose.
#[derive(Debug, Clone, PartialEq)]
struct BackdropKey {
    background: BackgroundConfig,
    lighting: LightingConfig,
}

impl BackdropKey {
    fn of(world: &World) -> Self {
        Self {
            background: world.scenario().background.clone(),
            lighting: world.scenario().lighting.clone(),
        }
    }
}

/// The backdrop (next row, ground, sky) does not move: it is rendered once per camera and
/// copied in at the start of every frame.
#[derive(Debug, Default)]
struct BackdropCache {
    key: Option<BackdropKey>,
    z_m: Vec<f32>,
    /// RGB8 (colour camera only).
    rgb: Vec<u8>,
}

impl RasterCamera {
    fn new(intrinsics: CameraIntrinsics, robot_from_camera: RigidTransform) -> Self {
        let width = intrinsics.width_px as usize;
        let height = intrinsics.height_px as usize;
        let rays = intrinsics.pixel_ray_table();
        Self {
            intrinsics,
            camera_from_robot: robot_from_camera.inverse(),
            robot_from_camera,
            width,
            height,
            rays,
            z_m: vec![f32::INFINITY; width * height],
            backdrop: BackdropCache::default(),
        }
    }

    /// Pixel box covering the normalised rectangle `[x0, x1] x [y0, y1]` after distortion
    /// (edges sampled, one pixel of margin), clipped to the image; `None` if outside.
    fn pixel_box(&self, x0: f64, x1: f64, y0: f64, y1: f64) -> Option<PixelBox> {
        const SAMPLES: usize = 4;
        let (mut u_min, mut u_max, mut v_min, mut v_max) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for k in 0..=SAMPLES {
            let f = k as f64 / SAMPLES as f64;
            let x = x0 + (x1 - x0) * f;
            let y = y0 + (y1 - y0) * f;
            for (xn, yn) in [(x, y0), (x, y1), (x0, y), (x1, y)] {
                let (u, v) = self.intrinsics.denormalize(xn, yn);
                u_min = u_min.min(u);
                u_max = u_max.max(u);
                v_min = v_min.min(v);
                v_max = v_max.max(v);
            }
        }
        let last_u = (self.width - 1) as f64;
        let last_v = (self.height - 1) as f64;
        if !(u_max >= 0.0 && v_max >= 0.0 && u_min <= last_u && v_min <= last_v) {
            return None;
        }
        Some(PixelBox {
            u0: (u_min - 1.0).floor().max(0.0) as usize,
            u1: (u_max + 1.0).ceil().min(last_u) as usize,
            v0: (v_min - 1.0).floor().max(0.0) as usize,
            v1: (v_max + 1.0).ceil().min(last_v) as usize,
        })
    }

    /// Pixel box of the projection of a convex hull given by its corner points (camera frame);
    /// `None` if any corner is behind the near plane or the box is off-image.
    fn hull_box(&self, corners: &[[f64; 3]]) -> Option<PixelBox> {
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for corner in corners {
            if corner[2] <= NEAR_M {
                return None;
            }
            let (x, y) = (corner[0] / corner[2], corner[1] / corner[2]);
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        self.pixel_box(x0, x1, y0, y1)
    }
}

/// An apple, in the camera frame.
#[derive(Debug, Clone, Copy)]
struct SpherePrim {
    center: V3,
    inv_radius: f32,
    /// `|c|^2 - r^2`.
    c_sq_minus_r_sq: f32,
    label: u32,
    blush: V3,
    ground: V3,
    blush_axis: V3,
    /// Blush where `n . axis > 1 - 2 f` (a cap of area fraction `f`).
    blush_cos: f32,
    /// Specular highlight of an over-exposed apple; `None` for a normally lit one.
    glare: Option<GlareDisc>,
    area: PixelBox,
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
struct DiscPrim {
    /// Unit normal pointing away from the camera.
    normal: V3,
    n_dot_c: f32,
    /// Coefficients of `A`.
    along: V3,
    /// Coefficients of `B`.
    across: V3,
    rgb: V3,
    area: PixelBox,
    depth_key: f32,
}

/// A branch, in the camera frame.
#[derive(Debug, Clone, Copy)]
struct CylinderPrim {
    start: V3,
    axis: V3,
    length: f32,
    inv_radius: f32,
    /// Component of `-start` perpendicular to the axis.
    w_perp: V3,
    /// `|w_perp|^2 - r^2`.
    w_perp_sq_minus_r_sq: f32,
    start_dot_axis: f32,
    rgb: V3,
    area: PixelBox,
}

/// The highlight disc of an over-exposed apple, in normalised image coordinates.
#[derive(Debug, Clone, Copy)]
struct GlareDisc {
    center: [f32; 2],
    inv_radius_sq: f32,
}

/// An over-exposed apple's highlight disc with its pixel box and the apple's label: only pixels
/// the apple itself wins are affected.
#[derive(Debug, Clone, Copy)]
struct GlarePrim {
    disc: GlareDisc,
    label: u32,
    area: PixelBox,
}

/// The world's objects in one camera's frame, rebuilt each frame into reused vectors.
#[derive(Debug, Default)]
struct Scene {
    spheres: Vec<SpherePrim>,
    discs: Vec<DiscPrim>,
    cylinders: Vec<CylinderPrim>,
    glare: Vec<GlarePrim>,
}

impl Scene {
    fn prepare(&mut self, world: &World, camera: &RasterCamera, patch_scale: f64) {
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

/// Background planes expressed for rays in one camera's frame.
#[derive(Debug, Clone, Copy)]
struct Backdrop {
    /// Rows of `robot_from_camera`'s rotation: robot x, y, z of a camera-frame direction.
    robot_x: V3,
    robot_y: V3,
    robot_z: V3,
    camera_in_robot: V3,
    next_row_x: f32,
    next_row_top_z: f32,
    ground_z: f32,
}

/// What the background ray hit.
#[derive(Debug, Clone, Copy)]
enum BackdropHit {
    Sky,
    /// Next tree row at depth `z`, robot `(y, z)` of the hit.
    NextRow {
        z: f32,
        y: f32,
        height: f32,
    },
    /// Ground at depth `z`, robot `(x, y)` of the hit.
    Ground {
        z: f32,
        x: f32,
        y: f32,
    },
}

impl Backdrop {
    fn new(world: &World, camera: &RasterCamera) -> Self {
        let r = camera.robot_from_camera.rotation;
        let b = &world.scenario().background;
        Self {
            robot_x: to_f32(r[0]),
            robot_y: to_f32(r[1]),
            robot_z: to_f32(r[2]),
            camera_in_robot: to_f32(camera.robot_from_camera.translation_m),
            next_row_x: b.next_row_x_m as f32,
            next_row_top_z: b.next_row_top_z_m as f32,
            ground_z: b.ground_z_m as f32,
        }
    }

    #[inline(always)]
    fn hit(&self, ray: [f32; 2]) -> BackdropHit {
        let d = [ray[0], ray[1], 1.0];
        let dx = dot(self.robot_x, d);
        let dz = dot(self.robot_z, d);
        let [tx, ty, tz] = self.camera_in_robot;
        if dx > 1e-6 {
            let t = (self.next_row_x - tx) / dx;
            let height = tz + dz * t;
            if height >= self.ground_z && height <= self.next_row_top_z {
                return BackdropHit::NextRow {
                    z: t,
                    y: ty + dot(self.robot_y, d) * t,
                    height,
                };
            }
        }
        if dz < -1e-6 {
            let t = (self.ground_z - tz) / dz;
            let x = tx + dx * t;
            if x <= self.next_row_x {
                return BackdropHit::Ground {
                    z: t,
                    x,
                    y: ty + dot(self.robot_y, d) * t,
                };
            }
        }
        BackdropHit::Sky
    }
}

/// Integer hash of the unit cell containing `(a, b)` to `[0, 1)`, for cheap procedural texture.
/// The offset keeps the truncating cast equal to `floor` for coordinates above -4096 cells.
#[inline(always)]
fn hash01(a: f32, b: f32) -> f32 {
    const OFFSET: f32 = 4096.0;
    let h = (((a + OFFSET) as u32).wrapping_mul(0x8da6_b343))
        ^ (((b + OFFSET) as u32).wrapping_mul(0xd816_3841));
    let h = (h ^ (h >> 13)).wrapping_mul(0x9e37_79b1);
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// What is done with a pixel once a surface wins its depth test.
trait Shader {
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, hit: V3);
    fn disc(&mut self, pixel: usize, prim: &DiscPrim, across: f32);
    fn cylinder(&mut self, pixel: usize, prim: &CylinderPrim, hit: V3, along: f32);
    fn backdrop(&mut self, pixel: usize, hit: BackdropHit);
}

/// Depth only: nothing but the z-buffer.
struct DepthOnly;

/// Depth plus, per pixel, the label of the apple that owns it (0 for anything else), so the
/// over-exposure pass can corrupt only the over-exposed apple's own pixels.
struct DepthOwners<'a> {
    owner: &'a mut [u32],
}

impl Shader for DepthOwners<'_> {
    #[inline(always)]
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, _: V3) {
        self.owner[pixel] = prim.label;
    }
    #[inline(always)]
    fn disc(&mut self, pixel: usize, _: &DiscPrim, _: f32) {
        self.owner[pixel] = 0;
    }
    #[inline(always)]
    fn cylinder(&mut self, pixel: usize, _: &CylinderPrim, _: V3, _: f32) {
        self.owner[pixel] = 0;
    }
    #[inline(always)]
    fn backdrop(&mut self, pixel: usize, _: BackdropHit) {
        self.owner[pixel] = 0;
    }
}

impl Shader for DepthOnly {
    #[inline(always)]
    fn sphere(&mut self, _: usize, _: &SpherePrim, _: V3) {}
    #[inline(always)]
    fn disc(&mut self, _: usize, _: &DiscPrim, _: f32) {}
    #[inline(always)]
    fn cylinder(&mut self, _: usize, _: &CylinderPrim, _: V3, _: f32) {}
    #[inline(always)]
    fn backdrop(&mut self, _: usize, _: BackdropHit) {}
}

/// Semantic labels (see [`label`]).
struct Labels<'a> {
    out: &'a mut [u32],
}

impl Shader for Labels<'_> {
    #[inline(always)]
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, _: V3) {
        self.out[pixel] = prim.label;
    }
    #[inline(always)]
    fn disc(&mut self, pixel: usize, _: &DiscPrim, _: f32) {
        self.out[pixel] = label::LEAF;
    }
    #[inline(always)]
    fn cylinder(&mut self, pixel: usize, _: &CylinderPrim, _: V3, _: f32) {
        self.out[pixel] = label::WOOD;
    }
    #[inline(always)]
    fn backdrop(&mut self, pixel: usize, hit: BackdropHit) {
        self.out[pixel] = match hit {
            BackdropHit::Sky => label::SKY,
            BackdropHit::NextRow { .. } => label::NEXT_ROW,
            BackdropHit::Ground { .. } => label::GROUND,
        };
    }
}

/// Lit RGB8.
struct Colors<'a> {
    out: &'a mut [u8],
    /// Unit vector towards the sun, camera frame.
    sun: V3,
    /// Blinn half vector between the sun and the viewing direction (-z).
    half: V3,
    sun_intensity: f32,
    ambient: f32,
    specular: f32,
    next_row: V3,
    ground: V3,
    sky: V3,
}

impl<'a> Colors<'a> {
    /// Lighting of `world` seen from a camera at `camera_from_robot`, writing into `out`.
    fn new(world: &World, camera_from_robot: &RigidTransform, out: &'a mut [u8]) -> Self {
        let scenario = world.scenario();
        let lighting = &scenario.lighting;
        let background = &scenario.background;
        let sun_in_camera = camera_from_robot.rotate(lighting.sun_direction_in_robot);
        let view = [0.0, 0.0, -1.0];
        let half = crate::scenario::normalized(std::array::from_fn(|k| sun_in_camera[k] + view[k]))
            .map_or(to_f32(view), to_f32);
        let linear = |rgb: [u8; 3]| rgb.map(|c| f32::from(c) / 255.0);
        Self {
            out,
            sun: to_f32(sun_in_camera),
            half,
            sun_intensity: lighting.sun_intensity as f32,
            ambient: lighting.ambient as f32,
            specular: lighting.specular as f32,
            next_row: linear(background.next_row_rgb),
            ground: linear(background.ground_rgb),
            sky: linear(background.sky_rgb),
        }
    }

    #[inline(always)]
    fn put(&mut self, pixel: usize, rgb: V3) {
        // Rounded; float-to-int `as` saturates, so values above 255 clip (over-exposure).
        if let Some(out) = self.out.get_mut(3 * pixel..3 * pixel + 3) {
            out[0] = (rgb[0] + 0.5) as u8;
            out[1] = (rgb[1] + 0.5) as u8;
            out[2] = (rgb[2] + 0.5) as u8;
        }
    }
}

impl Shader for Colors<'_> {
    #[inline(always)]
    fn sphere(&mut self, pixel: usize, prim: &SpherePrim, hit: V3) {
        let n = [
            (hit[0] - prim.center[0]) * prim.inv_radius,
            (hit[1] - prim.center[1]) * prim.inv_radius,
            (hit[2] - prim.center[2]) * prim.inv_radius,
        ];
        let diffuse = dot(n, self.sun).max(0.0);
        let mut highlight = dot(n, self.half).max(0.0);
        for _ in 0..4 {
            highlight *= highlight;
        }
        let blush = ((dot(n, prim.blush_axis) - prim.blush_cos) * 2.5 + 0.5).clamp(0.0, 1.0);
        let light = self.ambient + self.sun_intensity * diffuse;
        let shine = self.specular * self.sun_intensity * highlight * 255.0;
        let mut rgb: V3 = std::array::from_fn(|k| {
            let albedo = prim.ground[k] + (prim.blush[k] - prim.ground[k]) * blush;
            albedo * light * 255.0 + shine
        });
        if let Some(glare) = &prim.glare {
            // Sunlight reflected by the apple's own skin saturates it towards white. A later,
            // nearer leaf or branch overwrites this pixel with its own colour.
            let weight = glare_weight(glare, [hit[0] / hit[2], hit[1] / hit[2]]);
            if weight > 0.0 {
                let saturation = (1.6 * weight).min(1.0);
                for c in &mut rgb {
                    let clipped = c.clamp(0.0, 255.0);
                    *c = clipped + (255.0 - clipped) * saturation;
                }
            }
        }
        self.put(pixel, rgb);
    }

    #[inline(always)]
    fn disc(&mut self, pixel: usize, prim: &DiscPrim, across: f32) {
        // The side facing the camera has normal -n.
        let lit = -dot(prim.normal, self.sun);
        // Front-lit blades reflect; back-lit ones glow through (translucency).
        let diffuse = if lit > 0.0 { lit } else { -0.35 * lit };
        let vein = 0.8 + 0.2 * across.abs().min(1.0);
        let light = (self.ambient + self.sun_intensity * diffuse) * vein * 255.0;
        self.put(pixel, prim.rgb.map(|c| c * light));
    }

    #[inline(always)]
    fn cylinder(&mut self, pixel: usize, prim: &CylinderPrim, hit: V3, along: f32) {
        let n = std::array::from_fn(|k| {
            (hit[k] - prim.start[k] - along * prim.axis[k]) * prim.inv_radius
        });
        let diffuse = dot(n, self.sun).max(0.0);
        let bark = 0.85 + 0.3 * hash01(along * 60.0, 0.0);
        let light = (self.ambient + self.sun_intensity * diffuse) * bark * 255.0;
        self.put(pixel, prim.rgb.map(|c| c * light));
    }

    #[inline(always)]
    fn backdrop(&mut self, pixel: usize, hit: BackdropHit) {
        let rgb = match hit {
            BackdropHit::Sky => self.sky.map(|c| c * 255.0),
            BackdropHit::NextRow { y, height, .. } => {
                let texture = 0.55 + 0.6 * hash01(y * 22.0, height * 22.0);
                let light = (self.ambient + 0.5 * self.sun_intensity) * texture * 255.0;
                self.next_row.map(|c| c * light)
            }
            BackdropHit::Ground { x, y, .. } => {
                let texture = 0.8 + 0.35 * hash01(x * 18.0, y * 18.0);
                let light = (self.ambient + self.sun_intensity * self.sun[1].abs().max(0.3))
                    * texture
                    * 255.0;
                self.ground.map(|c| c * light)
            }
        };
        self.put(pixel, rgb);
    }
}

/// Intersects every pixel's ray with the backdrop, writing its depth (infinity for sky).
fn backdrop_pass<S: Shader>(
    rays: &[[f32; 2]],
    z_m: &mut [f32],
    backdrop: &Backdrop,
    shader: &mut S,
) {
    for (pixel, (z, ray)) in z_m.iter_mut().zip(rays).enumerate() {
        let hit = backdrop.hit(*ray);
        *z = match hit {
            BackdropHit::NextRow { z, .. } | BackdropHit::Ground { z, .. } => z,
            BackdropHit::Sky => f32::INFINITY,
        };
        shader.backdrop(pixel, hit);
    }
}

/// Image rows rasterised together: every object is clipped to one band at a time so the band's
/// rays, depths and colours stay in cache while all objects covering it are drawn (objects
/// overlap about three deep, and the RGB ray table alone is 16 MB).
const BAND_ROWS: usize = 16;

/// The rows of one band and the buffers they index.
struct Band<'a> {
    v0: usize,
    v1: usize,
    width: usize,
    rays: &'a [[f32; 2]],
    z_m: &'a mut [f32],
}

impl Band<'_> {
    /// Visits `(pixel, ray, depth)` for the part of `area` inside this band.
    #[inline(always)]
    fn for_each(&mut self, area: PixelBox, mut visit: impl FnMut(usize, [f32; 2], &mut f32)) {
        for v in area.v0.max(self.v0)..=area.v1.min(self.v1) {
            let start = v * self.width + area.u0;
            let end = v * self.width + area.u1 + 1;
            let row = self.rays[start..end]
                .iter()
                .zip(self.z_m[start..end].iter_mut());
            for (offset, (ray, z)) in row.enumerate() {
                visit(start + offset, *ray, z);
            }
        }
    }
}

impl Band<'_> {
    /// Draws a leaf into this band. Leaves are the bulk of the work, so each row is tested in
    /// chunks: first a branch-free pass computing which pixels the leaf wins (vectorisable),
    /// then the winners are written and shaded.
    #[inline(always)]
    fn draw_disc<S: Shader>(&mut self, prim: &DiscPrim, shader: &mut S) {
        const CHUNK: usize = 64;
        let (n, al, ac) = (prim.normal, prim.along, prim.across);
        let area = prim.area;
        let mut wins = [false; CHUNK];
        for v in area.v0.max(self.v0)..=area.v1.min(self.v1) {
            let row_start = v * self.width + area.u0;
            let row_end = v * self.width + area.u1 + 1;
            let mut start = row_start;
            while start < row_end {
                let end = (start + CHUNK).min(row_end);
                let rays = &self.rays[start..end];
                let z_m = &mut self.z_m[start..end];
                for ((win, &[x, y]), &z) in wins.iter_mut().zip(rays).zip(z_m.iter()) {
                    let facing = n[0] * x + n[1] * y + n[2];
                    let along = al[0] * x + al[1] * y + al[2];
                    let across = ac[0] * x + ac[1] * y + ac[2];
                    *win = (along * along + across * across <= facing * facing)
                        & (facing > 0.0)
                        & (prim.n_dot_c < z * facing);
                }
                for (offset, ((_, &[x, y]), z)) in wins
                    .iter()
                    .zip(rays)
                    .zip(z_m.iter_mut())
                    .enumerate()
                    .filter(|(_, ((win, _), _))| **win)
                {
                    let facing = n[0] * x + n[1] * y + n[2];
                    let across = ac[0] * x + ac[1] * y + ac[2];
                    *z = prim.n_dot_c / facing;
                    shader.disc(start + offset, prim, across / facing);
                }
                start = end;
            }
        }
    }
}

/// Draws every object of `scene` over what the camera's z-buffer (and the shader's output)
/// already hold.
fn rasterize<S: Shader>(camera: &mut RasterCamera, scene: &Scene, shader: &mut S) {
    let (width, height) = (camera.width, camera.height);
    for v0 in (0..height).step_by(BAND_ROWS) {
        let mut band = Band {
            v0,
            v1: band_rows_end(v0, height),
            width,
            rays: &camera.rays,
            z_m: &mut camera.z_m,
        };
        let overlaps = |area: &PixelBox| area.v0 <= band_rows_end(v0, height) && area.v1 >= v0;
        for prim in scene.discs.iter().filter(|p| overlaps(&p.area)) {
            band.draw_disc(prim, shader);
        }
        for prim in scene.spheres.iter().filter(|p| overlaps(&p.area)) {
            let [cx, cy, cz] = prim.center;
            band.for_each(prim.area, |pixel, [x, y], z| {
                let b = x * cx + y * cy + cz;
                let dd = x * x + y * y + 1.0;
                let disc = b * b - dd * prim.c_sq_minus_r_sq;
                if disc < 0.0 {
                    return;
                }
                let t = (b - disc.sqrt()) / dd;
                if t <= 0.0 || t >= *z {
                    return;
                }
                *z = t;
                shader.sphere(pixel, prim, [x * t, y * t, t]);
            });
        }
        for prim in scene.cylinders.iter().filter(|p| overlaps(&p.area)) {
            band.for_each(prim.area, |pixel, [x, y], z| {
                let d = [x, y, 1.0];
                let d_dot_a = dot(d, prim.axis);
                let quad = dot(d, d) - d_dot_a * d_dot_a;
                let half_b = dot(d, prim.w_perp);
                let disc = half_b * half_b - quad * prim.w_perp_sq_minus_r_sq;
                if disc < 0.0 || quad <= 0.0 {
                    return;
                }
                let t = (-half_b - disc.sqrt()) / quad;
                if t <= 0.0 || t >= *z {
                    return;
                }
                let along = t * d_dot_a - prim.start_dot_axis;
                if !(0.0..=prim.length).contains(&along) {
                    return;
                }
                *z = t;
                shader.cylinder(pixel, prim, [x * t, y * t, t], along);
            });
        }
    }
}

/// Last row of the band starting at `v0`.
fn band_rows_end(v0: usize, height: usize) -> usize {
    (v0 + BAND_ROWS).min(height) - 1
}

/// Renders the ToF camera's RGB, depth and label frames of a [`World`] into caller buffers.
///
/// Owns per-camera ray tables and z-buffers (allocated once); a frame allocates nothing beyond
/// the per-object lists, which are reused.
#[derive(Debug)]
pub struct RgbdRenderer {
    color: RasterCamera,
    depth: RasterCamera,
    camera: CameraConfig,
    scene: Scene,
    /// Per depth pixel, the label of the apple that won it (0 = not an apple); only filled for
    /// frames with over-exposed apples.
    depth_owner: Vec<u32>,
}

impl RgbdRenderer {
    /// Builds the RGB and depth sensors of `camera` (TL460 intrinsics; the depth sensor at
    /// `robot_from_camera`, the RGB sensor offset by `color_from_depth`).
    pub fn new(camera: &CameraConfig) -> Result<Self, RenderError> {
        let robot_from_depth = camera.robot_from_camera()?;
        let robot_from_color = robot_from_depth.compose(&camera.color_from_depth().inverse());
        Ok(Self {
            color: RasterCamera::new(camera.color_intrinsics(), robot_from_color),
            depth: RasterCamera::new(camera.depth_intrinsics(), robot_from_depth),
            camera: camera.clone(),
            scene: Scene::default(),
            depth_owner: Vec::new(),
        })
    }

    pub fn color_intrinsics(&self) -> &CameraIntrinsics {
        &self.color.intrinsics
    }

    pub fn depth_intrinsics(&self) -> &CameraIntrinsics {
        &self.depth.intrinsics
    }

    /// Pose of the RGB sensor's optical frame.
    pub fn robot_from_color(&self) -> RigidTransform {
        self.color.robot_from_camera
    }

    /// Pose of the depth sensor's optical frame (the scenario's `robot_from_camera`).
    pub fn robot_from_depth(&self) -> RigidTransform {
        self.depth.robot_from_camera
    }

    fn check_len(
        buffer: &'static str,
        camera: &RasterCamera,
        channels: usize,
        actual: usize,
    ) -> Result<(), RenderError> {
        let expected = camera.width * camera.height * channels;
        if actual == expected {
            Ok(())
        } else {
            Err(RenderError::BufferSize {
                buffer,
                expected,
                actual,
                width: camera.intrinsics.width_px,
                height: camera.intrinsics.height_px,
            })
        }
    }

    /// Renders the RGB8 frame (row-major, 3 bytes per pixel) into `rgb_out`.
    pub fn render_color(&mut self, world: &World, rgb_out: &mut [u8]) -> Result<(), RenderError> {
        Self::check_len("rgb", &self.color, 3, rgb_out.len())?;
        let key = BackdropKey::of(world);
        let camera = &mut self.color;
        if camera.backdrop.key.as_ref() != Some(&key) {
            let backdrop = Backdrop::new(world, camera);
            let cache = &mut camera.backdrop;
            cache.z_m.resize(camera.z_m.len(), f32::INFINITY);
            cache.rgb.resize(rgb_out.len(), 0);
            let mut shader = Colors::new(world, &camera.camera_from_robot, &mut cache.rgb);
            backdrop_pass(&camera.rays, &mut cache.z_m, &backdrop, &mut shader);
            cache.key = Some(key);
            tracing::debug!("rendered the rgb backdrop");
        }
        camera.z_m.copy_from_slice(&camera.backdrop.z_m);
        rgb_out.copy_from_slice(&camera.backdrop.rgb);
        self.scene
            .prepare(world, &self.color, self.camera.overexposed_patch_scale);
        // Over-exposed apples are saturated in the sphere shader, on their own pixels only.
        let mut shader = Colors::new(world, &self.color.camera_from_robot, rgb_out);
        rasterize(&mut self.color, &self.scene, &mut shader);
        tracing::trace!(
            apples = self.scene.spheres.len(),
            leaves = self.scene.discs.len(),
            "rendered rgb frame"
        );
        Ok(())
    }

    /// Renders the depth frame (row-major, millimetres, 0 = no return) into `depth_out_mm`.
    /// The noise is a function of the world seed and `frame_seq`, so a frame can be reproduced.
    pub fn render_depth(
        &mut self,
        world: &World,
        frame_seq: u64,
        depth_out_mm: &mut [u16],
    ) -> Result<(), RenderError> {
        Self::check_len("depth", &self.depth, 1, depth_out_mm.len())?;
        let key = BackdropKey::of(world);
        let camera = &mut self.depth;
        if camera.backdrop.key.as_ref() != Some(&key) {
            let backdrop = Backdrop::new(world, camera);
            let cache = &mut camera.backdrop;
            cache.z_m.resize(camera.z_m.len(), f32::INFINITY);
            backdrop_pass(&camera.rays, &mut cache.z_m, &backdrop, &mut DepthOnly);
            cache.key = Some(key);
            tracing::debug!("rendered the depth backdrop");
        }
        camera.z_m.copy_from_slice(&camera.backdrop.z_m);
        self.scene
            .prepare(world, &self.depth, self.camera.overexposed_patch_scale);
        if self.scene.glare.is_empty() {
            rasterize(&mut self.depth, &self.scene, &mut DepthOnly);
        } else {
            self.depth_owner.clear();
            self.depth_owner.resize(self.depth.z_m.len(), 0);
            let mut shader = DepthOwners {
                owner: &mut self.depth_owner,
            };
            rasterize(&mut self.depth, &self.scene, &mut shader);
        }
        let mut rng = SmallRng::seed_from_u64(
            world.seed() ^ DEPTH_NOISE_STREAM ^ frame_seq.wrapping_mul(0xa24b_aed4_963e_e407),
        );
        let camera = &self.camera;
        let sigma_const_m = (camera.depth_noise_mm / 1000.0) as f32;
        let sigma_fraction = camera.depth_noise_fraction as f32;
        // Over-exposed apples: extra noise and dropouts on their own pixels, tapering to the
        // highlight disc's edge.
        let width = self.depth.width;
        let gain = camera.overexposed_depth_noise_gain as f32;
        let dropout = camera.overexposed_dropout_probability as f32;
        for glare in &self.scene.glare {
            let a = glare.area;
            for v in a.v0..=a.v1 {
                for u in a.u0..=a.u1 {
                    let pixel = v * width + u;
                    if self.depth_owner.get(pixel) != Some(&glare.label) {
                        continue;
                    }
                    let weight = glare_weight(&glare.disc, self.depth.rays[pixel]);
                    let z = self.depth.z_m[pixel];
                    if weight <= 0.0 || !z.is_finite() {
                        continue;
                    }
                    if rng.random::<f32>() < dropout * weight {
                        self.depth.z_m[pixel] = f32::INFINITY;
                        continue;
                    }
                    let extra_gain = 1.0 + (gain - 1.0) * weight;
                    let extra_sigma = (sigma_const_m + sigma_fraction * z)
                        * (extra_gain * extra_gain - 1.0).sqrt();
                    let noise: f32 = rng.sample(StandardNormal);
                    self.depth.z_m[pixel] = z + extra_sigma * noise;
                }
            }
        }
        let [min_m, max_m] = camera.range_m.map(|r| r as f32);
        for (out, z) in depth_out_mm.iter_mut().zip(&self.depth.z_m) {
            let z = *z;
            *out = if z >= min_m && z <= max_m {
                let noise: f32 = rng.sample(StandardNormal);
                let z_mm = 1000.0 * (z + (sigma_const_m + sigma_fraction * z) * noise);
                // Rounded; 0 is reserved for "no return".
                (z_mm.clamp(1.0, f32::from(u16::MAX)) + 0.5) as u16
            } else {
                0
            };
        }
        tracing::trace!(frame_seq, "rendered depth frame");
        Ok(())
    }

    /// Renders per-pixel labels at RGB resolution (see [`label`]): ground truth for evaluating
    /// segmentation.
    pub fn render_labels(
        &mut self,
        world: &World,
        labels_out: &mut [u32],
    ) -> Result<(), RenderError> {
        Self::check_len("labels", &self.color, 1, labels_out.len())?;
        let mut shader = Labels { out: labels_out };
        let backdrop = Backdrop::new(world, &self.color);
        backdrop_pass(
            &self.color.rays,
            &mut self.color.z_m,
            &backdrop,
            &mut shader,
        );
        self.scene
            .prepare(world, &self.color, self.camera.overexposed_patch_scale);
        rasterize(&mut self.color, &self.scene, &mut shader);
        Ok(())
    }
}

/// Glare weight at a ray: `1 - (d / R)^2` inside the disc, else <= 0.
#[inline(always)]
fn glare_weight(glare: &GlareDisc, ray: [f32; 2]) -> f32 {
    let dx = ray[0] - glare.center[0];
    let dy = ray[1] - glare.center[1];
    1.0 - (dx * dx + dy * dy) * glare.inv_radius_sq
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    struct Frames {
        rgb: Vec<u8>,
        depth_mm: Vec<u16>,
        labels: Vec<u32>,
    }

    fn render(world: &World, frame_seq: u64) -> (RgbdRenderer, Frames) {
        let mut renderer = RgbdRenderer::new(&world.scenario().camera).expect("renderer");
        let color = *renderer.color_intrinsics();
        let depth = *renderer.depth_intrinsics();
        let color_px = (color.width_px * color.height_px) as usize;
        let mut frames = Frames {
            rgb: vec![0; 3 * color_px],
            depth_mm: vec![0; (depth.width_px * depth.height_px) as usize],
            labels: vec![0; color_px],
        };
        renderer.render_color(world, &mut frames.rgb).expect("rgb");
        renderer
            .render_depth(world, frame_seq, &mut frames.depth_mm)
            .expect("depth");
        renderer
            .render_labels(world, &mut frames.labels)
            .expect("labels");
        (renderer, frames)
    }

    fn ideal_world() -> World {
        World::generate(&Scenario::preset("ideal").expect("ideal"), 4).expect("world")
    }

    fn pixel_index(intrinsics: &CameraIntrinsics, u: f64, v: f64) -> usize {
        v.round() as usize * intrinsics.width_px as usize + u.round() as usize
    }

    #[test]
    fn projected_apple_centres_land_on_their_rendered_pixels() {
        let world = ideal_world();
        let (renderer, frames) = render(&world, 0);
        let color = renderer.color_intrinsics();
        let depth = renderer.depth_intrinsics();
        let color_from_robot = renderer.robot_from_color().inverse();
        let depth_from_robot = renderer.robot_from_depth().inverse();
        for apple in world.apples() {
            let in_color = color_from_robot.apply(apple.center_in_robot_m);
            let (u, v) = color.project(in_color).expect("in front");
            assert!(color.contains(u, v), "apple {:?} off-image", apple.id);
            let pixel = pixel_index(color, u, v);
            assert_eq!(apple_from_label(frames.labels[pixel]), Some(apple.id));
            let [r, g, b] = [0, 1, 2].map(|k| frames.rgb[3 * pixel + k]);
            assert!(
                r > g && r > b,
                "apple {:?} pixel is not red: {r} {g} {b}",
                apple.id
            );
            // Depth at the projected centre is the near surface: z_centre - r (to first order).
            let in_depth = depth_from_robot.apply(apple.center_in_robot_m);
            let (u, v) = depth.project(in_depth).expect("in front");
            let measured_mm = f64::from(frames.depth_mm[pixel_index(depth, u, v)]);
            let surface_mm = 1000.0 * (in_depth[2] - apple.radius_m);
            let sigma_mm = world.scenario().camera.depth_sigma_mm(surface_mm);
            assert!(
                (measured_mm - surface_mm).abs() < 5.0 * sigma_mm + 3.0,
                "apple {:?}: depth {measured_mm} mm, expected {surface_mm:.1} mm",
                apple.id
            );
        }
    }

    #[test]
    fn depth_noise_matches_the_spec_on_a_flat_patch() {
        // The next tree row is a plane of constant robot x; with a camera looking straight along
        // robot x it is a plane of constant depth.
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.apples.count = 0;
        scenario.camera.position_in_robot_m = [0.0, 0.0, 0.5];
        scenario.camera.look_at_in_robot_m = [3.0, 0.0, 0.5];
        let world = World::generate(&scenario, 9).expect("world");
        let mut renderer = RgbdRenderer::new(&scenario.camera).expect("renderer");
        let depth = *renderer.depth_intrinsics();
        let mut frame = vec![0u16; (depth.width_px * depth.height_px) as usize];
        let truth_mm = 1000.0 * scenario.background.next_row_x_m;
        let expected_sigma_mm = scenario.camera.depth_sigma_mm(truth_mm);
        let (mut sum, mut sum_sq, mut count) = (0.0f64, 0.0f64, 0usize);
        for frame_seq in 0..4 {
            renderer
                .render_depth(&world, frame_seq, &mut frame)
                .expect("depth");
            // A 200x100 patch around the centre, all on the next row.
            for v in 190..290 {
                for u in 220..420 {
                    let error = f64::from(frame[v * depth.width_px as usize + u]) - truth_mm;
                    sum += error;
                    sum_sq += error * error;
                    count += 1;
                }
            }
        }
        let mean = sum / count as f64;
        let std = (sum_sq / count as f64 - mean * mean).sqrt();
        // Standard error of the mean is sigma / sqrt(80000), about 0.04 mm.
        assert!(mean.abs() < 0.3, "mean error {mean} mm");
        // Rounding to whole millimetres adds 1/12 mm^2 of variance.
        let expected_std = (expected_sigma_mm.powi(2) + 1.0 / 12.0).sqrt();
        assert!(
            (std / expected_std - 1.0).abs() < 0.02,
            "std {std} mm, expected {expected_std} mm"
        );
    }

    #[test]
    fn out_of_range_reads_zero_and_sky_has_no_return() {
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.camera.look_at_in_robot_m = [2.0, 0.0, 2.5];
        let world = World::generate(&scenario, 1).expect("world");
        let (renderer, frames) = render(&world, 0);
        // Looking up: the top rows see sky.
        let width = renderer.depth_intrinsics().width_px as usize;
        assert!(frames.depth_mm[..width].iter().all(|&d| d == 0));
        assert!(frames.labels[..100].iter().all(|&l| l == label::SKY));
        let sky = scenario.background.sky_rgb;
        assert_eq!(&frames.rgb[..3], &sky);
    }

    #[test]
    fn occluding_leaves_hide_apple_pixels() {
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.failures.heavy_occlusion = 1.0;
        let world = World::generate(&scenario, 2).expect("world");
        let (_, occluded) = render(&world, 0);
        let (_, clear) = render(&ideal_world(), 0);
        let apple_pixels =
            |labels: &[u32]| labels.iter().filter(|&&l| l >= label::APPLE_BASE).count();
        let (hidden, visible) = (apple_pixels(&occluded.labels), apple_pixels(&clear.labels));
        assert!(
            hidden * 2 < visible,
            "occluded {hidden} vs clear {visible} apple pixels"
        );
    }

    #[test]
    fn overexposure_saturates_the_apple_and_corrupts_its_depth() {
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.failures.camera_overexposure = 1.0;
        let world = World::generate(&scenario, 4).expect("world");
        let (renderer, frames) = render(&world, 0);
        let (_, clean) = render(&ideal_world(), 0);
        let color = renderer.color_intrinsics();
        let color_from_robot = renderer.robot_from_color().inverse();
        for apple in world.apples() {
            let (u, v) = color
                .project(color_from_robot.apply(apple.center_in_robot_m))
                .expect("front");
            let pixel = pixel_index(color, u, v);
            assert!(
                frames.rgb[3 * pixel..3 * pixel + 3]
                    .iter()
                    .all(|&c| c == 255)
            );
        }
        let dropouts = |d: &[u16]| d.iter().filter(|&&z| z == 0).count();
        assert!(dropouts(&frames.depth_mm) > dropouts(&clean.depth_mm) + 100);
    }

    #[test]
    fn overexposure_leaves_occluders_in_their_own_colour() {
        // Every apple over-exposed and most of them behind extra leaves.
        let mut scenario = Scenario::preset("default").expect("default");
        scenario.failures.camera_overexposure = 1.0;
        scenario.failures.heavy_occlusion = 1.0;
        let world = World::generate(&scenario, 7).expect("world");
        let (_, glaring) = render(&world, 0);
        // The same world rendered without any highlight.
        let mut camera = scenario.camera.clone();
        camera.overexposed_patch_scale = 0.0;
        let mut renderer = RgbdRenderer::new(&camera).expect("renderer");
        let mut plain = vec![0u8; glaring.rgb.len()];
        renderer.render_color(&world, &mut plain).expect("rgb");
        let (mut occluder_pixels, mut saturated_apple_pixels) = (0usize, 0usize);
        for (pixel, &label) in glaring.labels.iter().enumerate() {
            let rgb = 3 * pixel..3 * pixel + 3;
            if apple_from_label(label).is_some() {
                if glaring.rgb[rgb.clone()] != plain[rgb.clone()]
                    && glaring.rgb[rgb].iter().all(|&c| c >= 250)
                {
                    saturated_apple_pixels += 1;
                }
            } else {
                assert_eq!(
                    glaring.rgb[rgb.clone()],
                    plain[rgb],
                    "pixel {pixel} (label {label}) changed by an apple's highlight"
                );
                if label == label::LEAF || label == label::WOOD {
                    occluder_pixels += 1;
                }
            }
        }
        assert!(
            occluder_pixels > 100_000,
            "{occluder_pixels} occluder pixels"
        );
        assert!(
            saturated_apple_pixels > 10_000,
            "{saturated_apple_pixels} saturated apple pixels"
        );
    }

    #[test]
    fn same_seed_and_frame_give_identical_frames() {
        let world =
            World::generate(&Scenario::preset("default").expect("default"), 21).expect("world");
        let (_, a) = render(&world, 5);
        let (_, b) = render(&world, 5);
        let (_, c) = render(&world, 6);
        assert!(a.rgb == b.rgb && a.depth_mm == b.depth_mm && a.labels == b.labels);
        assert!(a.depth_mm != c.depth_mm, "noise differs between frames");
        assert!(a.rgb == c.rgb);
    }

    #[test]
    fn wrong_buffer_sizes_are_refused() {
        let world = ideal_world();
        let mut renderer = RgbdRenderer::new(&world.scenario().camera).expect("renderer");
        let error = renderer
            .render_color(&world, &mut [0u8; 10])
            .expect_err("size");
        assert!(matches!(
            error,
            RenderError::BufferSize {
                buffer: "rgb",
                actual: 10,
                ..
            }
        ));
        assert!(renderer.render_depth(&world, 0, &mut [0u16; 10]).is_err());
    }
}
