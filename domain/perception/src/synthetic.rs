//! Synthetic orchard RGB-D frames with known apple positions, for tests and timing.
//!
//! Not a simulator (the sim process renders the robot's world); a small ray caster good enough to
//! exercise the pipeline: red Lambertian spheres with specular highlights (clipped at 255 under
//! strong light), green leaf discs in front of some fruit, a textured foliage background with
//! brown branches, sky (no ToF return) at the top, and a depth image from the separately posed
//! depth camera with TL460 noise, dropouts and flying pixels at fruit silhouettes.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

use crate::camera_setup::CameraSetup;
use crate::frame::{DepthView, RgbView};
use crate::noise_model::DepthNoiseModel;
use harvest_ipc::camera_model::CameraIntrinsics;

/// A spherical apple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyntheticApple {
    /// Centre in the colour camera frame, metres.
    pub center_in_camera_m: [f64; 3],
    pub radius_m: f64,
    /// Diffuse reflectance per channel, [0, 1].
    pub albedo: [f64; 3],
}

/// A leaf: a disc facing the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyntheticLeaf {
    pub center_in_camera_m: [f64; 3],
    pub radius_m: f64,
}

/// A branch drawn on the background, colour-image pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyntheticBranch {
    pub from_px: [f64; 2],
    pub to_px: [f64; 2],
    pub width_px: f64,
}

/// A scene in the colour camera frame.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticScene {
    pub apples: Vec<SyntheticApple>,
    pub leaves: Vec<SyntheticLeaf>,
    pub branches: Vec<SyntheticBranch>,
    /// Depth of the foliage wall behind the fruit, metres.
    pub background_depth_m: f64,
    /// Background points with `y` below this (higher in the image) are sky, metres.
    pub sky_below_y_m: f64,
    /// Illumination multiplier (1 normal; 3 strongly over-exposed).
    pub light_gain: f64,
    /// Multiplier of the TL460 depth noise.
    pub depth_noise_scale: f64,
    /// Fraction of depth samples with no return.
    pub depth_dropout_fraction: f64,
    /// Fraction of grazing fruit samples mixed with the background (ToF flying pixels).
    pub flying_pixel_fraction: f64,
    pub seed: u64,
}

/// Rendered frames owning their buffers.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticFrame {
    pub rgb: Vec<u8>,
    pub rgb_width_px: u32,
    pub rgb_height_px: u32,
    pub depth_mm: Vec<u16>,
    pub depth_width_px: u32,
    pub depth_height_px: u32,
}

impl SyntheticFrame {
    pub fn rgb_view(&self) -> RgbView<'_> {
        RgbView {
            width_px: self.rgb_width_px,
            height_px: self.rgb_height_px,
            data: &self.rgb,
        }
    }

    pub fn depth_view(&self) -> DepthView<'_> {
        DepthView {
            width_px: self.depth_width_px,
            height_px: self.depth_height_px,
            data: &self.depth_mm,
        }
    }
}

/// Integer hash -> [0, 1).
fn hash01(x: i64, y: i64, salt: u64) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ salt.wrapping_mul(0x1656_67B1_9E37_79F9);
    h ^= h >> 33;
    h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    h ^= h >> 33;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth value noise in [0, 1) with lattice spacing `cell` pixels.
fn value_noise(u: f64, v: f64, cell: f64, salt: u64) -> f64 {
    let (x, y) = (u / cell, v / cell);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (xi, yi) = (x0 as i64, y0 as i64);
    let a = hash01(xi, yi, salt);
    let b = hash01(xi + 1, yi, salt);
    let c = hash01(xi, yi + 1, salt);
    let d = hash01(xi + 1, yi + 1, salt);
    (a + (b - a) * sx) + ((c + (d - c) * sx) - (a + (b - a) * sx)) * sy
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalized(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// Nearest intersection parameter `t > 0` of `origin + t * dir` with a sphere.
fn ray_sphere(origin: [f64; 3], dir: [f64; 3], centre: [f64; 3], radius: f64) -> Option<f64> {
    let oc = [
        origin[0] - centre[0],
        origin[1] - centre[1],
        origin[2] - centre[2],
    ];
    let a = dot(dir, dir);
    let b = dot(oc, dir);
    let c = dot(oc, oc) - radius * radius;
    let discriminant = b * b - a * c;
    if discriminant < 0.0 {
        return None;
    }
    let t = (-b - discriminant.sqrt()) / a;
    (t > 0.0).then_some(t)
}

/// Intersection with a camera-facing disc (plane `z = centre.z`).
fn ray_disc(origin: [f64; 3], dir: [f64; 3], centre: [f64; 3], radius: f64) -> Option<f64> {
    if dir[2].abs() < 1e-12 {
        return None;
    }
    let t = (centre[2] - origin[2]) / dir[2];
    let p = [origin[0] + t * dir[0], origin[1] + t * dir[1]];
    let inside = (p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2) <= radius * radius;
    (t > 0.0 && inside).then_some(t)
}

/// Pixel bounds `(u0, u1, v0, v1)` (inclusive-exclusive) of a sphere of `radius` at `centre`
/// (camera frame of `camera`), with a margin.
fn pixel_bounds(
    camera: &CameraIntrinsics,
    centre: [f64; 3],
    radius: f64,
) -> Option<(usize, usize, usize, usize)> {
    let distance = dot(centre, centre).sqrt();
    if centre[2] <= radius || distance <= radius {
        return None;
    }
    let (u, v) = camera.project(centre)?;
    let half = camera.fx_px.max(camera.fy_px) * radius / (centre[2] - radius) * 1.2 + 3.0;
    let clamp_w = |x: f64| x.clamp(0.0, camera.width_px as f64) as usize;
    let clamp_h = |y: f64| y.clamp(0.0, camera.height_px as f64) as usize;
    let bounds = (
        clamp_w(u - half),
        clamp_w(u + half + 1.0),
        clamp_h(v - half),
        clamp_h(v + half + 1.0),
    );
    (bounds.0 < bounds.1 && bounds.2 < bounds.3).then_some(bounds)
}

/// Light direction (towards the light: upper left, in front of the canopy).
const LIGHT: [f64; 3] = [-0.42, -0.57, -0.70];

impl SyntheticScene {
    /// A random orchard view with `apple_count` apples 0.9-1.5 m away, about a quarter of them
    /// touching a neighbour, half as many leaves (half of them partly covering a fruit), four
    /// branches and sky at the top. Apples lie fully inside both cameras' images.
    pub fn orchard(cameras: &CameraSetup, apple_count: usize, seed: u64) -> Self {
        let mut rng = SmallRng::seed_from_u64(seed);
        let color = &cameras.color;
        let depth_from_color = cameras.color_from_depth.inverse();
        let mut apples: Vec<SyntheticApple> = Vec::new();
        let margin_px = 120.0;
        for _ in 0..apple_count * 200 {
            if apples.len() >= apple_count {
                break;
            }
            let radius_m = rng.random_range(0.036..0.048);
            let centre = if !apples.is_empty() && rng.random::<f64>() < 0.25 {
                let other = apples[rng.random_range(0..apples.len())];
                let angle = rng.random_range(0.0..std::f64::consts::TAU);
                let gap = other.radius_m + radius_m + 0.002;
                [
                    other.center_in_camera_m[0] + gap * angle.cos(),
                    other.center_in_camera_m[1] + gap * angle.sin(),
                    other.center_in_camera_m[2] + rng.random_range(-0.01..0.01),
                ]
            } else {
                let z = rng.random_range(0.9..1.5);
                let u = rng.random_range(margin_px..color.width_px as f64 - margin_px);
                let v = rng.random_range(margin_px + 150.0..color.height_px as f64 - margin_px);
                color.unproject(u, v, z)
            };
            let inside_color = color.project(centre).is_some_and(|(u, v)| {
                u > margin_px
                    && v > margin_px
                    && u < color.width_px as f64 - margin_px
                    && v < color.height_px as f64 - margin_px
            });
            let inside_depth = cameras
                .depth
                .project(depth_from_color.apply(centre))
                .is_some_and(|(u, v)| {
                    u > 30.0
                        && v > 30.0
                        && u < cameras.depth.width_px as f64 - 30.0
                        && v < cameras.depth.height_px as f64 - 30.0
                });
            let clear = apples.iter().all(|a| {
                let d = [
                    a.center_in_camera_m[0] - centre[0],
                    a.center_in_camera_m[1] - centre[1],
                    a.center_in_camera_m[2] - centre[2],
                ];
                dot(d, d).sqrt() > a.radius_m + radius_m + 0.0015
            });
            if inside_color && inside_depth && clear {
                apples.push(SyntheticApple {
                    center_in_camera_m: centre,
                    radius_m,
                    albedo: [
                        rng.random_range(0.62..0.85),
                        rng.random_range(0.04..0.14),
                        rng.random_range(0.05..0.13),
                    ],
                });
            }
        }
        let mut leaves = Vec::new();
        for i in 0..apple_count / 2 {
            if i % 2 == 0 && !apples.is_empty() {
                let apple = apples[rng.random_range(0..apples.len())];
                let angle = rng.random_range(0.0..std::f64::consts::TAU);
                let offset = apple.radius_m * rng.random_range(0.9..1.3);
                let c = apple.center_in_camera_m;
                leaves.push(SyntheticLeaf {
                    center_in_camera_m: [
                        c[0] + offset * angle.cos(),
                        c[1] + offset * angle.sin(),
                        c[2] - apple.radius_m - rng.random_range(0.02..0.06),
                    ],
                    radius_m: rng.random_range(0.02..0.03),
                });
            } else {
                let z = rng.random_range(0.8..1.8);
                let u = rng.random_range(0.0..color.width_px as f64);
                let v = rng.random_range(0.0..color.height_px as f64);
                leaves.push(SyntheticLeaf {
                    center_in_camera_m: color.unproject(u, v, z),
                    radius_m: rng.random_range(0.02..0.04),
                });
            }
        }
        let (w, h) = (color.width_px as f64, color.height_px as f64);
        let branches = (0..4)
            .map(|_| SyntheticBranch {
                from_px: [rng.random_range(0.0..w), h * rng.random_range(0.3..1.0)],
                to_px: [rng.random_range(0.0..w), h * rng.random_range(0.2..1.0)],
                width_px: rng.random_range(8.0..20.0),
            })
            .collect();
        Self {
            apples,
            leaves,
            branches,
            background_depth_m: 2.3,
            sky_below_y_m: -0.45,
            light_gain: 1.0,
            depth_noise_scale: 1.0,
            depth_dropout_fraction: 0.01,
            flying_pixel_fraction: 0.3,
            seed,
        }
    }

    fn background_rgb(&self, color: &CameraIntrinsics, u: usize, v: usize) -> [f64; 3] {
        let (uf, vf) = (u as f64, v as f64);
        let y_m = (vf - color.cy_px) / color.fy_px * self.background_depth_m;
        let jitter = hash01(u as i64, v as i64, self.seed) - 0.5;
        if y_m < self.sky_below_y_m {
            let t = vf / color.height_px as f64;
            return [
                150.0 + 40.0 * t + 6.0 * jitter,
                190.0 + 25.0 * t + 6.0 * jitter,
                240.0,
            ];
        }
        for branch in &self.branches {
            let [x0, y0] = branch.from_px;
            let [x1, y1] = branch.to_px;
            let (dx, dy) = (x1 - x0, y1 - y0);
            let length_sq = (dx * dx + dy * dy).max(1e-9);
            let t = (((uf - x0) * dx + (vf - y0) * dy) / length_sq).clamp(0.0, 1.0);
            let (px, py) = (x0 + t * dx - uf, y0 + t * dy - vf);
            if px * px + py * py <= (branch.width_px / 2.0).powi(2) {
                let shade = 0.8 + 0.4 * value_noise(uf, vf, 6.0, self.seed ^ 7);
                return [
                    95.0 * shade + 10.0 * jitter,
                    70.0 * shade + 10.0 * jitter,
                    50.0 * shade,
                ];
            }
        }
        let leafy = value_noise(uf, vf, 28.0, self.seed) * 0.7
            + value_noise(uf, vf, 7.0, self.seed ^ 3) * 0.3;
        let dark = [25.0, 60.0, 20.0];
        let light = [120.0, 170.0, 60.0];
        [
            dark[0] + (light[0] - dark[0]) * leafy + 20.0 * jitter,
            dark[1] + (light[1] - dark[1]) * leafy + 20.0 * jitter,
            dark[2] + (light[2] - dark[2]) * leafy + 12.0 * jitter,
        ]
    }

    /// Renders the colour image and the depth image of `cameras`.
    pub fn render(&self, cameras: &CameraSetup) -> SyntheticFrame {
        SyntheticFrame {
            rgb: self.render_rgb(&cameras.color),
            rgb_width_px: cameras.color.width_px,
            rgb_height_px: cameras.color.height_px,
            depth_mm: self.render_depth(cameras),
            depth_width_px: cameras.depth.width_px,
            depth_height_px: cameras.depth.height_px,
        }
    }

    fn render_rgb(&self, color: &CameraIntrinsics) -> Vec<u8> {
        let (w, h) = (color.width_px as usize, color.height_px as usize);
        let mut linear = vec![[0.0_f64; 3]; w * h];
        for v in 0..h {
            for u in 0..w {
                linear[v * w + u] = self.background_rgb(color, u, v);
            }
        }
        let mut nearest = vec![f64::INFINITY; w * h];
        let light = normalized(LIGHT);
        for apple in &self.apples {
            let c = apple.center_in_camera_m;
            let Some((u0, u1, v0, v1)) = pixel_bounds(color, c, apple.radius_m) else {
                continue;
            };
            for v in v0..v1 {
                for u in u0..u1 {
                    let (x, y) = color.normalize(u as f64, v as f64);
                    let dir = [x, y, 1.0];
                    let Some(t) = ray_sphere([0.0; 3], dir, c, apple.radius_m) else {
                        continue;
                    };
                    let index = v * w + u;
                    if t >= nearest[index] {
                        continue;
                    }
                    nearest[index] = t;
                    let p = [t * x, t * y, t];
                    let n = normalized([p[0] - c[0], p[1] - c[1], p[2] - c[2]]);
                    let diffuse = dot(n, light).max(0.0);
                    let view = normalized([-p[0], -p[1], -p[2]]);
                    let n_dot_l = dot(n, light);
                    let reflect = [
                        2.0 * n_dot_l * n[0] - light[0],
                        2.0 * n_dot_l * n[1] - light[1],
                        2.0 * n_dot_l * n[2] - light[2],
                    ];
                    let specular = dot(reflect, view).max(0.0).powi(40) * 230.0;
                    let jitter = 6.0 * (hash01(u as i64, v as i64, self.seed ^ 11) - 0.5);
                    let shade = 0.3 + 0.7 * diffuse;
                    linear[index] = [
                        apple.albedo[0] * 255.0 * shade + specular + jitter,
                        apple.albedo[1] * 255.0 * shade + specular + jitter,
                        apple.albedo[2] * 255.0 * shade + specular + jitter,
                    ];
                }
            }
        }
        for leaf in &self.leaves {
            let c = leaf.center_in_camera_m;
            let Some((u0, u1, v0, v1)) = pixel_bounds(color, c, leaf.radius_m) else {
                continue;
            };
            for v in v0..v1 {
                for u in u0..u1 {
                    let (x, y) = color.normalize(u as f64, v as f64);
                    let Some(t) = ray_disc([0.0; 3], [x, y, 1.0], c, leaf.radius_m) else {
                        continue;
                    };
                    let index = v * w + u;
                    if t >= nearest[index] {
                        continue;
                    }
                    nearest[index] = t;
                    let shade = 0.75 + 0.3 * value_noise(u as f64, v as f64, 5.0, self.seed ^ 5);
                    linear[index] = [50.0 * shade, 125.0 * shade, 35.0 * shade];
                }
            }
        }
        let mut rgb = Vec::with_capacity(w * h * 3);
        for pixel in &linear {
            for channel in pixel {
                rgb.push((channel * self.light_gain).round().clamp(0.0, 255.0) as u8);
            }
        }
        rgb
    }

    fn render_depth(&self, cameras: &CameraSetup) -> Vec<u16> {
        let depth = &cameras.depth;
        let (w, h) = (depth.width_px as usize, depth.height_px as usize);
        let depth_from_color = cameras.color_from_depth.inverse();
        let origin = cameras.color_from_depth.translation_m;
        let noise = DepthNoiseModel::TL460;
        let mut rng = SmallRng::seed_from_u64(self.seed ^ 0xDEE9);
        // Nearest hit per pixel: depth-frame z (= ray parameter) and whether it grazes a fruit.
        let mut nearest = vec![f64::INFINITY; w * h];
        let mut grazing = vec![false; w * h];
        let ray_of = |u: usize, v: usize| {
            let (x, y) = depth.normalize(u as f64, v as f64);
            cameras.color_from_depth.rotate([x, y, 1.0])
        };
        for apple in &self.apples {
            let c = apple.center_in_camera_m;
            let Some((u0, u1, v0, v1)) =
                pixel_bounds(depth, depth_from_color.apply(c), apple.radius_m)
            else {
                continue;
            };
            for v in v0..v1 {
                for u in u0..u1 {
                    let dir = ray_of(u, v);
                    let Some(t) = ray_sphere(origin, dir, c, apple.radius_m) else {
                        continue;
                    };
                    let index = v * w + u;
                    if t < nearest[index] {
                        nearest[index] = t;
                        let p = [
                            origin[0] + t * dir[0],
                            origin[1] + t * dir[1],
                            origin[2] + t * dir[2],
                        ];
                        let n = normalized([p[0] - c[0], p[1] - c[1], p[2] - c[2]]);
                        grazing[index] = -dot(n, normalized(dir)) < 0.3;
                    }
                }
            }
        }
        for leaf in &self.leaves {
            let c = leaf.center_in_camera_m;
            let Some((u0, u1, v0, v1)) =
                pixel_bounds(depth, depth_from_color.apply(c), leaf.radius_m)
            else {
                continue;
            };
            for v in v0..v1 {
                for u in u0..u1 {
                    let dir = ray_of(u, v);
                    let Some(t) = ray_disc(origin, dir, c, leaf.radius_m) else {
                        continue;
                    };
                    let index = v * w + u;
                    if t < nearest[index] {
                        nearest[index] = t;
                        grazing[index] = false;
                    }
                }
            }
        }
        let mut depth_mm = vec![0_u16; w * h];
        for v in 0..h {
            for u in 0..w {
                let index = v * w + u;
                let dir = ray_of(u, v);
                let t_background = (self.background_depth_m - origin[2]) / dir[2];
                let background_y = origin[1] + t_background * dir[1];
                let is_sky = background_y < self.sky_below_y_m;
                let mut z = nearest[index];
                if !z.is_finite() {
                    if is_sky {
                        continue;
                    }
                    z = t_background;
                } else if grazing[index] && rng.random::<f64>() < self.flying_pixel_fraction {
                    let far = if is_sky { z + 0.5 } else { t_background };
                    z += (far - z) * rng.random::<f64>();
                }
                if rng.random::<f64>() < self.depth_dropout_fraction {
                    continue;
                }
                let gaussian: f64 = StandardNormal.sample(&mut rng);
                z += self.depth_noise_scale * noise.sigma_m(z) * gaussian;
                depth_mm[index] = (z * 1000.0).round().clamp(0.0, f64::from(u16::MAX)) as u16;
            }
        }
        depth_mm
    }
}
