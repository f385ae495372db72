//! Rendering of one calibration view as the colour camera images it: the checkerboard hanging in
//! the air in front of a cluttered background. The image side of the target-based calibration
//! ([fusion sec. II-C-1]) then finds the board's corners in these pixels
//! ([`crate::lidar::image_corners`]) instead of being handed their true projections.
//!
//! The picture is formed the way a camera forms it:
//! - geometry: each pixel on the board's image is traced back through the lens. The corners of
//!   its footprint are undistorted into rays ([`CameraIntrinsics::normalize`], the inverse of
//!   the distortion that [`CameraIntrinsics::project`] applies) and intersected with the board
//!   plane (for a flat board, a homography from normalized image coordinates to the board).
//!   A pixel whose footprint lies in one square, border strip or background zone gets that
//!   colour; one that straddles an edge is supersampled (n x n, bilinear in its footprint), so
//!   edges are anti-aliased. Only the board's bounding box is traced; the rest is background.
//! - paper: white about 215 and black about 30 of 255, under a mild light gradient;
//! - background: a smooth gradient, low-frequency shading and clutter (rectangles, discs,
//!   bars and striped patches of random grey), so the detector is not handed a clean image;
//! - optics and sensor: Gaussian blur, Gaussian grey-level noise, 8-bit quantization.

use crate::lidar::checkerboard::Checkerboard;
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use nalgebra::{Matrix3, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// An 8-bit grey image, row-major. Pixel `(u, v)` is centred at integer coordinates and covers
/// `[u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]` (the camera model's pixel convention).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GreyImage {
    pub width_px: usize,
    pub height_px: usize,
    pub pixels: Vec<u8>,
}

impl GreyImage {
    /// An image of one grey level.
    pub fn filled(width_px: usize, height_px: usize, grey: u8) -> Self {
        Self {
            width_px,
            height_px,
            pixels: vec![grey; width_px * height_px],
        }
    }

    /// Grey level at pixel `(u, v)`; `None` outside the image.
    pub fn get(&self, u: usize, v: usize) -> Option<u8> {
        if u >= self.width_px || v >= self.height_px {
            return None;
        }
        self.pixels.get(v * self.width_px + u).copied()
    }
}

/// How a view is rendered.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoardImageConfig {
    /// Grey level of the white paper in full light, of 255.
    pub white_grey: f64,
    /// Grey level of the black print in full light, of 255.
    pub black_grey: f64,
    /// Change of the light from the board's centre to its edge, relative (random direction).
    pub light_gradient: f64,
    /// Sensor noise, one standard deviation, grey levels.
    pub noise_grey: f64,
    /// Optical blur, one standard deviation of a Gaussian, pixels.
    pub blur_px: f64,
    /// Samples per pixel side where a pixel straddles an edge (anti-aliasing).
    pub supersampling: usize,
    /// Clutter items in the background.
    pub clutter_items: usize,
}

impl Default for BoardImageConfig {
    fn default() -> Self {
        Self {
            white_grey: 215.0,
            black_grey: 30.0,
            light_gradient: 0.06,
            noise_grey: 2.0,
            blur_px: 0.7,
            supersampling: 4,
            clutter_items: 60,
        }
    }
}

impl BoardImageConfig {
    /// Checks the values; the error names the key and value.
    pub fn validate(&self) -> Result<(), String> {
        for (key, value) in [
            ("white_grey", self.white_grey),
            ("black_grey", self.black_grey),
        ] {
            if !(value.is_finite() && (0.0..=255.0).contains(&value)) {
                return Err(format!("{key} = {value} outside 0..=255"));
            }
        }
        if !(self.light_gradient.is_finite() && (0.0..0.5).contains(&self.light_gradient)) {
            return Err(format!(
                "light_gradient = {} outside 0..0.5",
                self.light_gradient
            ));
        }
        for (key, value) in [("noise_grey", self.noise_grey), ("blur_px", self.blur_px)] {
            if !(value.is_finite() && (0.0..=20.0).contains(&value)) {
                return Err(format!("{key} = {value} outside 0..=20"));
            }
        }
        if !(1..=16).contains(&self.supersampling) {
            return Err(format!(
                "supersampling = {} outside 1..=16",
                self.supersampling
            ));
        }
        if self.clutter_items > 10_000 {
            return Err(format!(
                "clutter_items = {} above 10000",
                self.clutter_items
            ));
        }
        Ok(())
    }
}

/// Why a view could not be rendered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// A configuration value is unusable.
    #[error("board image: {0}")]
    Config(String),
    /// The camera looks at the board's back or along its plane.
    #[error(
        "the board is seen from behind or edge-on (cosine between its normal and the line of \
         sight {facing:.3})"
    )]
    NotFacing { facing: f64 },
    /// Part of the board is behind the camera.
    #[error("part of the board is behind the camera")]
    BehindCamera,
}

/// Renders `board` at `camera_from_board` as the camera `intrinsics` sees it; `rng` draws the
/// background, the light and the noise.
pub fn render_board_view(
    intrinsics: &CameraIntrinsics,
    board: &Checkerboard,
    camera_from_board: &RigidTransform,
    config: &BoardImageConfig,
    rng: &mut impl Rng,
) -> Result<GreyImage, RenderError> {
    config.validate().map_err(RenderError::Config)?;
    board.validate().map_err(RenderError::Config)?;
    let (width, height) = (intrinsics.width_px as usize, intrinsics.height_px as usize);
    if width == 0 || height == 0 {
        return Err(RenderError::Config(format!(
            "camera image {width} x {height} px is empty"
        )));
    }
    let r = camera_from_board.rotation;
    let t = camera_from_board.translation_m;
    let distance = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    // Board z points away from the camera: the line of sight to the centre runs along it.
    let facing = (r[0][2] * t[0] + r[1][2] * t[1] + r[2][2] * t[2]) / distance.max(1e-12);
    if facing.is_nan() || facing <= 0.05 {
        return Err(RenderError::NotFacing { facing });
    }
    let mut canvas = background(width, height, config, rng);
    let light = Light::sample(board, config, rng);
    // Normalized image coordinates (x/z, y/z, 1) ~ [r1 r2 t] (board x, board y, 1).
    let normalized_from_board = Matrix3::new(
        r[0][0], r[0][1], t[0], r[1][0], r[1][1], t[1], r[2][0], r[2][1], t[2],
    );
    let board_from_normalized = normalized_from_board
        .try_inverse()
        .ok_or(RenderError::NotFacing { facing })?;
    if let Some(region) = board_region(intrinsics, board, camera_from_board)? {
        draw_board(
            &mut canvas,
            width,
            intrinsics,
            board,
            &board_from_normalized,
            &light,
            config.supersampling,
            region,
        );
    }
    if config.blur_px > 0.0 {
        gaussian_blur(&mut canvas, width, height, config.blur_px);
    }
    let noise = Normal::new(0.0, config.noise_grey.max(1e-12))
        .map_err(|error| RenderError::Config(error.to_string()))?;
    let pixels = canvas
        .iter()
        .map(|&value| {
            let noisy = if config.noise_grey > 0.0 {
                f64::from(value) + noise.sample(rng)
            } else {
                f64::from(value)
            };
            noisy.round().clamp(0.0, 255.0) as u8
        })
        .collect();
    Ok(GreyImage {
        width_px: width,
        height_px: height,
        pixels,
    })
}

/// The light on the board: an overall gain and a linear gradient across it.
#[derive(Debug, Clone, Copy)]
struct Light {
    gain: f64,
    per_m: [f64; 2],
    white_grey: f64,
    black_grey: f64,
}

impl Light {
    fn sample(board: &Checkerboard, config: &BoardImageConfig, rng: &mut impl Rng) -> Self {
        let angle = rng.random_range(0.0..std::f64::consts::TAU);
        let half_diagonal_m = 0.5 * board.width_m().hypot(board.height_m());
        let slope = config.light_gradient / half_diagonal_m;
        Self {
            gain: rng.random_range(0.96..=1.02),
            per_m: [slope * angle.cos(), slope * angle.sin()],
            white_grey: config.white_grey,
            black_grey: config.black_grey,
        }
    }

    fn grey(&self, white: bool, x_m: f64, y_m: f64) -> f32 {
        let paper = if white {
            self.white_grey
        } else {
            self.black_grey
        };
        let light = self.gain * (1.0 + self.per_m[0] * x_m + self.per_m[1] * y_m);
        (paper * light).clamp(0.0, 255.0) as f32
    }
}

/// Pixel bounding box `[u0, v0, u1, v1]` (inclusive) of the board's image, clipped to the image;
/// `None` when the board is outside it.
fn board_region(
    intrinsics: &CameraIntrinsics,
    board: &Checkerboard,
    camera_from_board: &RigidTransform,
) -> Result<Option<[usize; 4]>, RenderError> {
    const SAMPLES_PER_EDGE: usize = 32;
    const MARGIN_PX: f64 = 2.0;
    let (half_w, half_h) = (board.width_m() / 2.0, board.height_m() / 2.0);
    let mut bounds = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for k in 0..SAMPLES_PER_EDGE {
        let s = k as f64 / SAMPLES_PER_EDGE as f64;
        let along_x = -half_w + 2.0 * half_w * s;
        let along_y = -half_h + 2.0 * half_h * s;
        for [x, y] in [
            [along_x, -half_h],
            [half_w, along_y],
            [-along_x, half_h],
            [-half_w, -along_y],
        ] {
            let (u, v) = intrinsics
                .project(camera_from_board.apply([x, y, 0.0]))
                .ok_or(RenderError::BehindCamera)?;
            bounds = [
                bounds[0].min(u),
                bounds[1].min(v),
                bounds[2].max(u),
                bounds[3].max(v),
            ];
        }
    }
    let (width, height) = (intrinsics.width_px as f64, intrinsics.height_px as f64);
    let u0 = (bounds[0] - MARGIN_PX).floor().max(0.0);
    let v0 = (bounds[1] - MARGIN_PX).floor().max(0.0);
    let u1 = (bounds[2] + MARGIN_PX).ceil().min(width - 1.0);
    let v1 = (bounds[3] + MARGIN_PX).ceil().min(height - 1.0);
    if !(u0 <= u1 && v0 <= v1) {
        return Ok(None);
    }
    Ok(Some([u0 as usize, v0 as usize, u1 as usize, v1 as usize]))
}

/// Which convex piece of the board plane a point lies in: a square, one of the eight border
/// strips or corners, or one of the eight zones off the board. A pixel whose four footprint
/// corners share a piece lies in it entirely (pieces are convex, footprints nearly parallelograms).
fn piece(board: &Checkerboard, x_m: f64, y_m: f64) -> (i64, i64) {
    let columns = (board.inner_columns + 1) as i64;
    let rows = (board.inner_rows + 1) as i64;
    let axis = |value: f64, half_outer: f64, half_pattern: f64, count: i64| -> i64 {
        if value < -half_outer {
            -2
        } else if value > half_outer {
            count + 1
        } else {
            let cell = ((value + half_pattern) / board.square_m).floor();
            (cell.clamp(-1.0, count as f64) as i64).min(count)
        }
    };
    let half_pattern_w = columns as f64 * board.square_m / 2.0;
    let half_pattern_h = rows as f64 * board.square_m / 2.0;
    (
        axis(x_m, board.width_m() / 2.0, half_pattern_w, columns),
        axis(y_m, board.height_m() / 2.0, half_pattern_h, rows),
    )
}

/// Traces the pixels of `region` onto the board and paints them over the background.
#[allow(clippy::too_many_arguments)]
fn draw_board(
    canvas: &mut [f32],
    width: usize,
    intrinsics: &CameraIntrinsics,
    board: &Checkerboard,
    board_from_normalized: &Matrix3<f64>,
    light: &Light,
    supersampling: usize,
    [u0, v0, u1, v1]: [usize; 4],
) {
    // Board coordinates of the pixel-footprint corners (u - 0.5, v - 0.5) of the region.
    let grid_w = u1 - u0 + 2;
    let grid_h = v1 - v0 + 2;
    let mut grid = Vec::with_capacity(grid_w * grid_h);
    for gv in 0..grid_h {
        for gu in 0..grid_w {
            let (x, y) = intrinsics.normalize((u0 + gu) as f64 - 0.5, (v0 + gv) as f64 - 0.5);
            let b = board_from_normalized * Vector3::new(x, y, 1.0);
            // A ray meeting the plane behind the camera or not at all: off the board.
            grid.push(if b.z > 1e-12 {
                [b.x / b.z, b.y / b.z]
            } else {
                [f64::INFINITY, f64::INFINITY]
            });
        }
    }
    let n = supersampling;
    let inv_samples = 1.0 / (n * n) as f32;
    for v in v0..=v1 {
        for u in u0..=u1 {
            let g = (v - v0) * grid_w + (u - u0);
            let corners = [grid[g], grid[g + 1], grid[g + grid_w], grid[g + grid_w + 1]];
            let index = v * width + u;
            let background = canvas[index];
            let pieces = corners.map(|[x, y]| piece(board, x, y));
            if pieces.iter().all(|p| *p == pieces[0]) {
                let x = corners.iter().map(|c| c[0]).sum::<f64>() / 4.0;
                let y = corners.iter().map(|c| c[1]).sum::<f64>() / 4.0;
                if let Some(white) = board.is_white(x, y) {
                    canvas[index] = light.grey(white, x, y);
                }
                continue;
            }
            let [c00, c10, c01, c11] = corners;
            let mut sum = 0.0f32;
            for sy in 0..n {
                let fy = (sy as f64 + 0.5) / n as f64;
                for sx in 0..n {
                    let fx = (sx as f64 + 0.5) / n as f64;
                    let lerp = |k: usize| {
                        (1.0 - fy) * ((1.0 - fx) * c00[k] + fx * c10[k])
                            + fy * ((1.0 - fx) * c01[k] + fx * c11[k])
                    };
                    let (x, y) = (lerp(0), lerp(1));
                    sum += match board.is_white(x, y) {
                        Some(white) if x.is_finite() && y.is_finite() => light.grey(white, x, y),
                        _ => background,
                    };
                }
            }
            canvas[index] = sum * inv_samples;
        }
    }
}

/// The scene behind the board: gradient, shading waves and clutter, grey levels as `f32`.
fn background(
    width: usize,
    height: usize,
    config: &BoardImageConfig,
    rng: &mut impl Rng,
) -> Vec<f32> {
    let base = rng.random_range(70.0..150.0f32);
    let slope = [
        rng.random_range(-60.0..60.0f32) / width as f32,
        rng.random_range(-60.0..60.0f32) / height as f32,
    ];
    let waves: Vec<([f32; 2], f32, f32)> = (0..2)
        .map(|_| {
            let angle = rng.random_range(0.0..std::f32::consts::TAU);
            let wavelength_px = rng.random_range(250.0..900.0f32);
            let k = std::f32::consts::TAU / wavelength_px;
            (
                [k * angle.cos(), k * angle.sin()],
                rng.random_range(0.0..std::f32::consts::TAU),
                rng.random_range(4.0..12.0f32),
            )
        })
        .collect();
    // sin(a + b) = sin a cos b + cos a sin b, with a per column and b per row: no sine per pixel.
    let columns: Vec<Vec<(f32, f32)>> = waves
        .iter()
        .map(|([kx, _], phase, _)| {
            (0..width)
                .map(|u| (kx * u as f32 + phase).sin_cos())
                .collect()
        })
        .collect();
    let mut canvas = Vec::with_capacity(width * height);
    for v in 0..height {
        let y = v as f32;
        let rows: Vec<(f32, f32, f32)> = waves
            .iter()
            .map(|([_, ky], _, amplitude)| {
                let (sin, cos) = (ky * y).sin_cos();
                (sin, cos, *amplitude)
            })
            .collect();
        for u in 0..width {
            let mut value = base + slope[0] * u as f32 + slope[1] * y;
            for (column, (sin_b, cos_b, amplitude)) in columns.iter().zip(&rows) {
                let (sin_a, cos_a) = column[u];
                value += amplitude * (sin_a * cos_b + cos_a * sin_b);
            }
            canvas.push(value);
        }
    }
    for _ in 0..config.clutter_items {
        let item = Clutter::sample(width, height, rng);
        item.paint(&mut canvas, width, height);
    }
    canvas
}

/// One background object: a rotated box (rectangle, bar or striped patch) or a disc.
#[derive(Debug, Clone, Copy)]
struct Clutter {
    centre: [f32; 2],
    /// Half extents of a box; `[radius, 0]` for a disc.
    half: [f32; 2],
    angle_rad: f32,
    disc: bool,
    grey: f32,
    /// Stripe period and second grey for striped patches.
    stripes: Option<(f32, f32)>,
}

impl Clutter {
    fn sample(width: usize, height: usize, rng: &mut impl Rng) -> Self {
        let centre = [
            rng.random_range(0.0..width as f32),
            rng.random_range(0.0..height as f32),
        ];
        let grey = rng.random_range(15.0..240.0f32);
        let angle_rad = rng.random_range(0.0..std::f32::consts::PI);
        match rng.random_range(0..4u8) {
            0 => Self {
                centre,
                half: [rng.random_range(8.0..90.0), 0.0],
                angle_rad,
                disc: true,
                grey,
                stripes: None,
            },
            1 => Self {
                centre,
                half: [rng.random_range(40.0..400.0), rng.random_range(1.5..6.0)],
                angle_rad,
                disc: false,
                grey,
                stripes: None,
            },
            2 => Self {
                centre,
                half: [rng.random_range(15.0..80.0), rng.random_range(15.0..80.0)],
                angle_rad,
                disc: false,
                grey,
                stripes: Some((rng.random_range(5.0..24.0), rng.random_range(15.0..240.0))),
            },
            _ => Self {
                centre,
                half: [rng.random_range(10.0..160.0), rng.random_range(10.0..120.0)],
                angle_rad,
                disc: false,
                grey,
                stripes: None,
            },
        }
    }

    fn paint(&self, canvas: &mut [f32], width: usize, height: usize) {
        let reach = if self.disc {
            self.half[0]
        } else {
            self.half[0].hypot(self.half[1])
        } + 1.0;
        let u0 = (self.centre[0] - reach).floor().max(0.0) as usize;
        let v0 = (self.centre[1] - reach).floor().max(0.0) as usize;
        let u1 = ((self.centre[0] + reach).ceil().max(0.0) as usize).min(width.saturating_sub(1));
        let v1 = ((self.centre[1] + reach).ceil().max(0.0) as usize).min(height.saturating_sub(1));
        let (sin, cos) = self.angle_rad.sin_cos();
        for v in v0..=v1 {
            for u in u0..=u1 {
                let dx = u as f32 - self.centre[0];
                let dy = v as f32 - self.centre[1];
                let (lx, ly) = (cos * dx + sin * dy, -sin * dx + cos * dy);
                // Signed distance to the outline (approximate for box corners), for a soft edge.
                let outside = if self.disc {
                    lx.hypot(ly) - self.half[0]
                } else {
                    (lx.abs() - self.half[0]).max(ly.abs() - self.half[1])
                };
                let coverage = (0.5 - outside).clamp(0.0, 1.0);
                if coverage <= 0.0 {
                    continue;
                }
                let grey = match self.stripes {
                    Some((period, other)) if (lx / period).rem_euclid(2.0) >= 1.0 => other,
                    _ => self.grey,
                };
                let cell = &mut canvas[v * width + u];
                *cell += coverage * (grey - *cell);
            }
        }
    }
}

/// In-place separable Gaussian blur (edges clamped).
fn gaussian_blur(canvas: &mut [f32], width: usize, height: usize, sigma_px: f64) {
    let radius = (3.0 * sigma_px).ceil() as isize;
    let mut kernel: Vec<f32> = (-radius..=radius)
        .map(|k| (-((k * k) as f64) / (2.0 * sigma_px * sigma_px)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|w| *w /= total);
    let mut scratch = vec![0.0f32; canvas.len()];
    let clamp = |value: isize, limit: usize| value.clamp(0, limit as isize - 1) as usize;
    for v in 0..height {
        let row = &canvas[v * width..(v + 1) * width];
        for u in 0..width {
            scratch[v * width + u] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| w * row[clamp(u as isize + k as isize - radius, width)])
                .sum();
        }
    }
    for v in 0..height {
        for u in 0..width {
            canvas[v * width + u] = kernel
                .iter()
                .enumerate()
                .map(|(k, w)| {
                    w * scratch[clamp(v as isize + k as isize - radius, height) * width + u]
                })
                .sum();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::SmallRng;

    fn facing_pose(distance_m: f64) -> RigidTransform {
        RigidTransform::from_rpy_translation(0.1, -0.2, 0.03, [0.05, -0.02, distance_m])
    }

    #[test]
    fn squares_have_paper_grey_levels_and_edges_are_anti_aliased() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let board = Checkerboard::paper();
        let pose = facing_pose(1.5);
        let config = BoardImageConfig {
            noise_grey: 0.0,
            blur_px: 0.0,
            light_gradient: 0.0,
            ..BoardImageConfig::default()
        };
        let mut rng = SmallRng::seed_from_u64(3);
        let image =
            render_board_view(&intrinsics, &board, &pose, &config, &mut rng).expect("render");
        assert_eq!(image.pixels.len(), 1920 * 1080);
        // Square centres: black for (0, 0), white for (1, 0), within the light gain.
        let grey_at = |x: f64, y: f64| {
            let (u, v) = intrinsics
                .project(pose.apply([x, y, 0.0]))
                .expect("in front");
            f64::from(
                image
                    .get(u.round() as usize, v.round() as usize)
                    .expect("inside"),
            )
        };
        let [x0, y0] = board.corner_m(0, 0);
        let half = board.square_m / 2.0;
        let black = grey_at(x0 - half, y0 - half);
        let white = grey_at(x0 + half, y0 - half);
        assert!((20.0..=40.0).contains(&black), "black {black}");
        assert!((200.0..=230.0).contains(&white), "white {white}");
        // Across a vertical square edge the grey levels step through intermediate values.
        let (u, v) = intrinsics
            .project(pose.apply([x0, y0 - half, 0.0]))
            .expect("edge");
        let row: Vec<u8> = (0..7)
            .map(|k| {
                image
                    .get(u.round() as usize + k - 3, v.round() as usize)
                    .expect("in")
            })
            .collect();
        let intermediate = row.iter().filter(|&&g| g > 45 && g < 195).count();
        assert!((1..=2).contains(&intermediate), "edge profile {row:?}");
    }

    #[test]
    fn background_is_not_uniform_and_bad_inputs_are_named() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let board = Checkerboard::paper();
        let mut rng = SmallRng::seed_from_u64(4);
        let image = render_board_view(
            &intrinsics,
            &board,
            &facing_pose(2.5),
            &BoardImageConfig::default(),
            &mut rng,
        )
        .expect("render");
        // The top-left 200 x 200 px (background) spans many grey levels.
        let mut levels = std::collections::BTreeSet::new();
        for v in 0..200 {
            for u in 0..200 {
                levels.insert(image.get(u, v).expect("inside"));
            }
        }
        assert!(levels.len() > 20, "{} grey levels", levels.len());
        let backwards =
            RigidTransform::from_rpy_translation(0.0, std::f64::consts::PI, 0.0, [0.0, 0.0, 2.0]);
        let error = render_board_view(
            &intrinsics,
            &board,
            &backwards,
            &BoardImageConfig::default(),
            &mut rng,
        )
        .expect_err("seen from behind");
        assert!(matches!(error, RenderError::NotFacing { .. }), "{error}");
        let bad = BoardImageConfig {
            supersampling: 0,
            ..BoardImageConfig::default()
        };
        let error = render_board_view(&intrinsics, &board, &facing_pose(2.0), &bad, &mut rng)
            .expect_err("no samples");
        assert!(error.to_string().contains("supersampling = 0"), "{error}");
    }
}
