//! LiDAR-camera fusion ([fusion sec. II-B]): every LiDAR point `L_p` is moved into
//! the colour camera frame by the extrinsic `camera_from_lidar` (the paper's `T_L^C`) and
//! projected through the intrinsics `K` and the lens distortion `pi` (eq. 1-2):
//! `p_uv = pi(K T_L^C L_p)`.
//!
//! One [`Fusion::fuse`] call gives
//! - the **registered depth image** at colour resolution: per pixel the camera-frame depth `z`
//!   of the nearest point that projects there (0 = no point); LiDAR points are sparse, so most
//!   pixels stay empty (about 100k of 2M pixels for a 1 s cloud);
//! - for every point its pixel, so the **colourised cloud** ([`Fusion::colorize`]) and the points
//!   under an instance mask ([`Fusion::points_in_mask`]) follow without projecting again.
//!
//! Bad points are counted, not fatal: non-finite coordinates (the device's "no return"), points
//! at or behind the camera (`z <= MIN_DEPTH_M`), points projecting outside the image.
//!
//! Occlusion: the LiDAR sits a few centimetres from the camera, so it sees some background the
//! camera does not (beside a fruit, behind its rim). Projected, those points land inside the
//! fruit's image, where they would corrupt its mask points. Each projected point is therefore
//! splatted into a coarse occlusion buffer (cells of `occlusion_cell_px` pixels) over a square of
//! `2 * occlusion_splat_cells + 1` cells, wider than the spacing of the integrated points (about
//! 5-8 px at 1920x1080 for a 0.5-1 s cloud), so a surface's points cover its image; a point more
//! than `occlusion_tolerance_m` behind the nearest splat at its cell is occluded: it gets no
//! colour, is in no mask and not in the registered depth image. Near depth edges this also drops
//! a few background points the camera does see (conservative for fruit masks).
//!
//! Cost: one rigid transform and one distorted projection per point, the splats, a clear of the
//! occlusion buffer and a sparse reset of the previous frame's depth pixels; the buffers are
//! allocated once. [`measure_fusion_time`] reports the time per cloud.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};
use harvest_ipc::payloads::{LidarPoint, RgbdFrameMeta};

/// The largest image a fusion fills: a colour frame's, px.
const MAX_IMAGE_PIXELS: usize = RGB_WIDTH_PX * RGB_HEIGHT_PX;
use std::time::Instant;

/// Points closer to the camera plane than this (camera z, metres) are treated as behind it.
pub const MIN_DEPTH_M: f64 = 0.05;

/// Marker in [`Fusion::point_pixels`] for a point that has no pixel.
pub const NO_PIXEL: u32 = u32::MAX;

/// What became of one point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointFate {
    /// Projected into the image and visible to the camera.
    Visible,
    /// NaN or infinite coordinates.
    NonFinite,
    /// At or behind the camera plane.
    BehindCamera,
    /// Projects outside the image.
    OutsideImage,
    /// Projects into the image behind a nearer point in the same pixel.
    Occluded,
}

/// Counts of one fusion.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FusionStats {
    pub points: usize,
    pub visible: usize,
    pub non_finite: usize,
    pub behind_camera: usize,
    pub outside_image: usize,
    pub occluded: usize,
    /// Pixels of the registered depth image that received a depth.
    pub depth_pixels: usize,
}

/// Why a cloud could not be fused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FusionError {
    /// The cloud holds no point at all.
    #[error("empty point cloud: nothing to fuse (is the LiDAR streaming?)")]
    EmptyCloud,
    /// No point of the cloud is finite.
    #[error("all {points} points of the cloud are NaN or infinite")]
    NoFinitePoint { points: usize },
    /// The colour image passed to [`Fusion::colorize`] does not match the intrinsics.
    #[error("colour image has {actual} bytes; a {width}x{height} RGB8 image needs {expected}")]
    ImageSize {
        expected: usize,
        actual: usize,
        width: u32,
        height: u32,
    },
    /// The intrinsics or extrinsic are unusable.
    #[error("fusion setup: {0}")]
    Setup(String),
}

/// Occlusion tolerance in range-noise sigmas (see [`FusionConfig::with_range_noise`]).
pub const OCCLUSION_TOLERANCE_SIGMAS: f64 = 7.0;

/// Fusion settings.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FusionConfig {
    /// Colour camera intrinsics (with distortion).
    pub intrinsics: CameraIntrinsics,
    /// The extrinsic `T_L^C`: LiDAR frame -> colour camera frame.
    pub camera_from_lidar: RigidTransform,
    /// A point more than this behind the nearest splat at its pixel is occluded, metres.
    pub occlusion_tolerance_m: f64,
    /// Edge of one cell of the occlusion buffer, pixels.
    pub occlusion_cell_px: u32,
    /// Half size of the square of cells each point covers in the occlusion buffer (0 = its own
    /// cell only).
    pub occlusion_splat_cells: u32,
}

impl FusionConfig {
    /// Fusion into the ToF camera's *depth* image geometry (its intrinsics, `depth_from_lidar`
    /// from the frame's `color_from_depth` registration), so [`Fusion::write_depth_mm`] gives a
    /// drop-in replacement for `RgbdFrame::depth_mm` (640x480, millimetres, 0 = no point) that a
    /// consumer of the ToF frames can use as its depth source unchanged.
    pub fn for_tof_depth(meta: &RgbdFrameMeta, camera_from_lidar: RigidTransform) -> Self {
        let depth_from_lidar = meta.color_from_depth.inverse().compose(&camera_from_lidar);
        Self::new(meta.depth_intrinsics, depth_from_lidar)
    }

    /// Sizes the occlusion test for points whose range errs by `range_sigma_m` (one sigma): a
    /// point counts as hidden when it lies further than [`OCCLUSION_TOLERANCE_SIGMAS`] sigmas
    /// (at least the default 5 cm) behind the nearest point around its pixel. The nearest of the
    /// tens to hundreds of noisy returns around a pixel lies 2-3.5 sigmas in front of the
    /// surface, so a fixed 5 cm drops the far part of a 2 cm-noise LiDAR's returns on every
    /// surface and pulls the depth towards the camera.
    pub fn with_range_noise(mut self, range_sigma_m: f64) -> Self {
        self.occlusion_tolerance_m = self
            .occlusion_tolerance_m
            .max(OCCLUSION_TOLERANCE_SIGMAS * range_sigma_m);
        self
    }

    /// Default occlusion settings for a camera and extrinsic.
    pub fn new(intrinsics: CameraIntrinsics, camera_from_lidar: RigidTransform) -> Self {
        Self {
            intrinsics,
            camera_from_lidar,
            occlusion_tolerance_m: 0.05,
            occlusion_cell_px: 4,
            occlusion_splat_cells: 1,
        }
    }
}

/// A point of the colourised cloud.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColoredPoint {
    /// Position in the colour camera frame, metres.
    pub position_in_camera_m: [f32; 3],
    pub rgb: [u8; 3],
    /// LiDAR intensity of the return.
    pub intensity: f32,
}

/// Projects clouds into one camera; owns the registered depth image and per-point results.
#[derive(Debug)]
pub struct Fusion {
    config: FusionConfig,
    width: usize,
    height: usize,
    /// Registered depth (camera z, metres), row-major at colour resolution; 0 = no point. The
    /// mean of the unoccluded points that fall into the pixel: the minimum would pull the depth
    /// towards the camera by the range noise.
    depth_m: Vec<f32>,
    /// Points averaged into each touched pixel of `depth_m` (zeroed with it).
    depth_samples: Vec<u32>,
    /// Pixels written by the last fusion (to reset them sparsely).
    touched: Vec<u32>,
    /// Nearest splatted depth per occlusion cell (camera z, metres; infinity = none).
    occlusion_m: Vec<f32>,
    occlusion_width: usize,
    occlusion_height: usize,
    /// Per point of the last cloud: pixel index or [`NO_PIXEL`].
    point_pixels: Vec<u32>,
    /// Per point of the last cloud: position in the camera frame (NaN when not finite).
    points_in_camera_m: Vec<[f32; 3]>,
    intensities: Vec<f32>,
    fates: Vec<PointFate>,
}

impl Fusion {
    /// Allocates the buffers for `config.intrinsics`' image size.
    pub fn new(config: FusionConfig) -> Result<Self, FusionError> {
        let k = &config.intrinsics;
        if let Some(problem) = k.problem() {
            return Err(FusionError::Setup(problem));
        }
        let t = &config.camera_from_lidar;
        if !t
            .rotation
            .iter()
            .flatten()
            .chain(&t.translation_m)
            .all(|v| v.is_finite())
        {
            return Err(FusionError::Setup(format!(
                "camera_from_lidar {t:?} has non-finite entries"
            )));
        }
        if !(1..=64).contains(&config.occlusion_cell_px) || config.occlusion_splat_cells > 16 {
            return Err(FusionError::Setup(format!(
                "occlusion_cell_px = {} (1..=64) or occlusion_splat_cells = {} (0..=16) out of range",
                config.occlusion_cell_px, config.occlusion_splat_cells
            )));
        }
        if !(config.occlusion_tolerance_m.is_finite() && config.occlusion_tolerance_m >= 0.0) {
            return Err(FusionError::Setup(format!(
                "occlusion_tolerance_m = {} is not a non-negative number",
                config.occlusion_tolerance_m
            )));
        }
        let (width, height) = (k.width_px as usize, k.height_px as usize);
        // The image size comes with the frames (shared memory): bound it by the largest camera
        // image a frame carries before allocating per pixel.
        if width == 0 || height == 0 || width.saturating_mul(height) > MAX_IMAGE_PIXELS {
            return Err(FusionError::Setup(format!(
                "image {width}x{height} px is empty or larger than a camera frame's \
                 {RGB_WIDTH_PX}x{RGB_HEIGHT_PX} px"
            )));
        }
        let cell = config.occlusion_cell_px as usize;
        let (occlusion_width, occlusion_height) = (width.div_ceil(cell), height.div_ceil(cell));
        Ok(Self {
            config,
            width,
            height,
            depth_m: vec![0.0; width * height],
            depth_samples: vec![0; width * height],
            touched: Vec::new(),
            occlusion_m: vec![f32::INFINITY; occlusion_width * occlusion_height],
            occlusion_width,
            occlusion_height,
            point_pixels: Vec::new(),
            points_in_camera_m: Vec::new(),
            intensities: Vec::new(),
            fates: Vec::new(),
        })
    }

    pub fn config(&self) -> &FusionConfig {
        &self.config
    }

    /// Replaces the extrinsic (after a new calibration).
    pub fn set_camera_from_lidar(&mut self, camera_from_lidar: RigidTransform) {
        self.config.camera_from_lidar = camera_from_lidar;
    }

    /// Fuses one cloud (LiDAR frame): eq. 2 for every point, z-buffered into the registered
    /// depth image.
    pub fn fuse(&mut self, points: &[LidarPoint]) -> Result<FusionStats, FusionError> {
        for &pixel in &self.touched {
            self.depth_m[pixel as usize] = 0.0;
            self.depth_samples[pixel as usize] = 0;
        }
        self.touched.clear();
        self.point_pixels.clear();
        self.points_in_camera_m.clear();
        self.intensities.clear();
        self.fates.clear();
        if points.is_empty() {
            return Err(FusionError::EmptyCloud);
        }
        let transform = self.config.camera_from_lidar;
        let intrinsics = self.config.intrinsics;
        let mut stats = FusionStats {
            points: points.len(),
            ..FusionStats::default()
        };
        for point in points {
            self.intensities.push(point.intensity);
            if !point.is_finite() {
                stats.non_finite += 1;
                self.push(NO_PIXEL, [f32::NAN; 3], PointFate::NonFinite);
                continue;
            }
            let in_camera = transform.apply(point.position_m().map(f64::from));
            let in_camera_f32 = in_camera.map(|v| v as f32);
            if in_camera[2] <= MIN_DEPTH_M {
                stats.behind_camera += 1;
                self.push(NO_PIXEL, in_camera_f32, PointFate::BehindCamera);
                continue;
            }
            let pixel = intrinsics
                .project(in_camera)
                .filter(|&(u, v)| intrinsics.contains(u, v))
                .map(|(u, v)| {
                    let u = (u.round() as usize).min(self.width - 1);
                    let v = (v.round() as usize).min(self.height - 1);
                    v * self.width + u
                });
            let Some(pixel) = pixel else {
                stats.outside_image += 1;
                self.push(NO_PIXEL, in_camera_f32, PointFate::OutsideImage);
                continue;
            };
            self.push(pixel as u32, in_camera_f32, PointFate::Visible);
        }
        if stats.non_finite == points.len() {
            return Err(FusionError::NoFinitePoint {
                points: points.len(),
            });
        }
        // Second pass: splat every projected point into the occlusion buffer.
        self.occlusion_m.fill(f32::INFINITY);
        let splat = self.config.occlusion_splat_cells as usize;
        let cell_px = self.config.occlusion_cell_px as usize;
        let (width, cells_w, cells_h) = (self.width, self.occlusion_width, self.occlusion_height);
        for ((fate, &pixel), point) in self
            .fates
            .iter()
            .zip(&self.point_pixels)
            .zip(&self.points_in_camera_m)
        {
            if *fate != PointFate::Visible {
                continue;
            }
            let (cu, cv) = (
                pixel as usize % width / cell_px,
                pixel as usize / width / cell_px,
            );
            let (u0, u1) = (cu.saturating_sub(splat), (cu + splat).min(cells_w - 1));
            for row in cv.saturating_sub(splat)..=(cv + splat).min(cells_h - 1) {
                for cell in &mut self.occlusion_m[row * cells_w + u0..=row * cells_w + u1] {
                    *cell = cell.min(point[2]);
                }
            }
        }
        // Third pass: points well behind the nearest splat at their pixel are occluded; the
        // others enter the registered depth image.
        let tolerance = self.config.occlusion_tolerance_m as f32;
        for ((fate, &pixel), point) in self
            .fates
            .iter_mut()
            .zip(&self.point_pixels)
            .zip(&self.points_in_camera_m)
        {
            if *fate != PointFate::Visible {
                continue;
            }
            let pixel = pixel as usize;
            let cell = pixel / width / cell_px * cells_w + pixel % width / cell_px;
            if point[2] > self.occlusion_m[cell] + tolerance {
                *fate = PointFate::Occluded;
                stats.occluded += 1;
                continue;
            }
            stats.visible += 1;
            if self.depth_samples[pixel] == 0 {
                self.touched.push(pixel as u32);
            }
            self.depth_m[pixel] += point[2];
            self.depth_samples[pixel] += 1;
        }
        for &pixel in &self.touched {
            let pixel = pixel as usize;
            self.depth_m[pixel] /= self.depth_samples[pixel] as f32;
        }
        stats.depth_pixels = self.touched.len();
        tracing::trace!(?stats, "cloud fused");
        Ok(stats)
    }

    fn push(&mut self, pixel: u32, in_camera: [f32; 3], fate: PointFate) {
        self.point_pixels.push(pixel);
        self.points_in_camera_m.push(in_camera);
        self.fates.push(fate);
    }

    /// Registered depth image of the last fusion (camera z, metres; 0 = no point), row-major at
    /// the colour image's resolution.
    pub fn depth_m(&self) -> &[f32] {
        &self.depth_m
    }

    /// Depth at a colour pixel, `None` where no point landed.
    pub fn depth_at_m(&self, u_px: usize, v_px: usize) -> Option<f32> {
        if u_px >= self.width || v_px >= self.height {
            return None;
        }
        Some(self.depth_m[v_px * self.width + u_px]).filter(|&z| z > 0.0)
    }

    /// Writes the registered depth in millimetres (0 = no point) into `out_mm` (colour
    /// resolution), for consumers of the `RgbdFrame` depth convention.
    pub fn write_depth_mm(&self, out_mm: &mut [u16]) -> Result<(), FusionError> {
        if out_mm.len() != self.depth_m.len() {
            return Err(FusionError::ImageSize {
                expected: self.depth_m.len(),
                actual: out_mm.len(),
                width: self.config.intrinsics.width_px,
                height: self.config.intrinsics.height_px,
            });
        }
        out_mm.fill(0);
        for &pixel in &self.touched {
            let z_mm = self.depth_m[pixel as usize] * 1000.0;
            out_mm[pixel as usize] = (z_mm.clamp(1.0, f32::from(u16::MAX)) + 0.5) as u16;
        }
        Ok(())
    }

    /// Per point of the last cloud: its pixel index (`v * width + u`) or [`NO_PIXEL`].
    pub fn point_pixels(&self) -> &[u32] {
        &self.point_pixels
    }

    /// Per point of the last cloud: what became of it.
    pub fn fates(&self) -> &[PointFate] {
        &self.fates
    }

    /// Per point of the last cloud: position in the camera frame, metres.
    pub fn points_in_camera_m(&self) -> &[[f32; 3]] {
        &self.points_in_camera_m
    }

    /// The colourised cloud of the last fusion: every visible point with the colour of its
    /// pixel in `rgb` (RGB8, row-major, the camera's resolution), replacing `out`.
    pub fn colorize(&self, rgb: &[u8], out: &mut Vec<ColoredPoint>) -> Result<(), FusionError> {
        let expected = self.width * self.height * 3;
        if rgb.len() != expected {
            return Err(FusionError::ImageSize {
                expected,
                actual: rgb.len(),
                width: self.config.intrinsics.width_px,
                height: self.config.intrinsics.height_px,
            });
        }
        out.clear();
        for (((fate, &pixel), point), &intensity) in self
            .fates
            .iter()
            .zip(&self.point_pixels)
            .zip(&self.points_in_camera_m)
            .zip(&self.intensities)
        {
            if *fate != PointFate::Visible {
                continue;
            }
            let at = 3 * pixel as usize;
            out.push(ColoredPoint {
                position_in_camera_m: *point,
                rgb: [rgb[at], rgb[at + 1], rgb[at + 2]],
                intensity,
            });
        }
        Ok(())
    }

    /// The camera-frame positions of the visible points whose pixel is in the mask
    /// (`in_mask(pixel_index)`), replacing `out`: the paper's `C_P_mask` of one fruit.
    pub fn points_in_mask(&self, in_mask: impl Fn(usize) -> bool, out: &mut Vec<[f32; 3]>) {
        out.clear();
        for ((fate, &pixel), point) in self
            .fates
            .iter()
            .zip(&self.point_pixels)
            .zip(&self.points_in_camera_m)
        {
            if *fate == PointFate::Visible && in_mask(pixel as usize) {
                out.push(*point);
            }
        }
    }
}

/// Time of [`Fusion::fuse`] for one cloud, measured on the calling thread.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FusionTiming {
    pub points: usize,
    pub width_px: u32,
    pub height_px: u32,
    pub runs: usize,
    pub median_ms: f64,
    pub max_ms: f64,
}

/// Fuses `points` `runs` times into a fresh [`Fusion`] and reports the median and worst time.
/// A measurement, not a test: run it in a release build.
pub fn measure_fusion_time(
    config: FusionConfig,
    points: &[LidarPoint],
    runs: usize,
) -> Result<FusionTiming, FusionError> {
    let mut fusion = Fusion::new(config)?;
    fusion.fuse(points)?;
    let mut times_ms = Vec::with_capacity(runs.max(1));
    for _ in 0..runs.max(1) {
        let started = Instant::now();
        fusion.fuse(points)?;
        times_ms.push(started.elapsed().as_secs_f64() * 1e3);
    }
    times_ms.sort_by(f64::total_cmp);
    Ok(FusionTiming {
        points: points.len(),
        width_px: config.intrinsics.width_px,
        height_px: config.intrinsics.height_px,
        runs: times_ms.len(),
        median_ms: times_ms[times_ms.len() / 2],
        max_ms: times_ms[times_ms.len() - 1],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::lidar::OPTICAL_FROM_LIDAR;

    fn config(distortion: [f64; 5]) -> FusionConfig {
        let mut intrinsics = CameraIntrinsics::from_horizontal_fov(640, 480, 60.0);
        intrinsics.distortion = distortion;
        // LiDAR 0.1 m above the camera, boresight along the optical axis.
        FusionConfig::new(
            intrinsics,
            RigidTransform {
                rotation: OPTICAL_FROM_LIDAR.rotation,
                translation_m: [0.0, -0.1, 0.0],
            },
        )
    }

    fn lidar_point(x: f32, y: f32, z: f32) -> LidarPoint {
        LidarPoint {
            x_m: x,
            y_m: y,
            z_m: z,
            intensity: 50.0,
        }
    }

    #[test]
    fn known_points_land_on_known_pixels() {
        for distortion in [[0.0; 5], [-0.04, 0.01, 0.001, -0.002, 0.0]] {
            let config = config(distortion);
            let k = config.intrinsics;
            let mut fusion = Fusion::new(config).expect("fusion");
            // LiDAR (forward 2 m, left 0.3, up 0.2) -> camera (x = -0.3, y = -0.2 - 0.1, z = 2).
            let stats = fusion.fuse(&[lidar_point(2.0, 0.3, 0.2)]).expect("fuse");
            assert_eq!(stats.visible, 1);
            let (x, y) = (-0.3 / 2.0, -0.3 / 2.0);
            let (xd, yd) = k.distort(x, y);
            let (u, v) = (k.fx_px * xd + k.cx_px, k.fy_px * yd + k.cy_px);
            let pixel = fusion.point_pixels()[0] as usize;
            assert_eq!(pixel, v.round() as usize * 640 + u.round() as usize);
            let depth = fusion
                .depth_at_m(u.round() as usize, v.round() as usize)
                .expect("depth");
            assert!((depth - 2.0).abs() < 1e-6);
            let p = fusion.points_in_camera_m()[0];
            assert!((p[0] + 0.3).abs() < 1e-6 && (p[1] + 0.3).abs() < 1e-6);
        }
    }

    #[test]
    fn bad_points_are_counted_and_dropped() {
        let mut fusion = Fusion::new(config([0.0; 5])).expect("fusion");
        let points = [
            lidar_point(f32::NAN, 0.0, 0.0),
            lidar_point(-1.0, 0.0, 0.0), // behind the camera
            lidar_point(0.01, 0.0, 0.1), // at the camera plane
            lidar_point(1.0, 5.0, 0.0),  // far off to the left: outside the image
            lidar_point(3.0, 0.0, 0.1),  // visible, on the optical axis
            lidar_point(6.0, 0.0, 0.3),  // same ray, 3 m further: occluded
        ];
        let stats = fusion.fuse(&points).expect("fuse");
        assert_eq!(stats.points, 6);
        assert_eq!(stats.non_finite, 1);
        assert_eq!(stats.behind_camera, 2);
        assert_eq!(stats.outside_image, 1);
        assert_eq!(stats.visible, 1);
        assert_eq!(stats.occluded, 1);
        assert_eq!(stats.depth_pixels, 1);
        use PointFate::*;
        assert_eq!(
            fusion.fates(),
            &[
                NonFinite,
                BehindCamera,
                BehindCamera,
                OutsideImage,
                Visible,
                Occluded
            ]
        );
        let rgb = vec![7u8; 640 * 480 * 3];
        let mut colored = Vec::new();
        fusion.colorize(&rgb, &mut colored).expect("colorize");
        assert_eq!(colored.len(), 1);
        assert_eq!(colored[0].rgb, [7, 7, 7]);
        assert!(fusion.colorize(&rgb[..10], &mut colored).is_err());
    }

    #[test]
    fn background_seen_only_by_the_lidar_is_occluded_behind_a_near_surface() {
        // A near wall patch 1 m ahead, sampled every 8 mm (4.4 px), and a background point 3 m
        // ahead whose ray passes between the wall's points (2.2 px from the nearest): the
        // camera cannot see it, and no wall point shares its pixel.
        let mut fusion = Fusion::new(config([0.0; 5])).expect("fusion");
        let mut points = Vec::new();
        for i in -5..=5 {
            for j in -5..=5 {
                points.push(lidar_point(1.0, 0.008 * i as f32, -0.1 + 0.008 * j as f32));
            }
        }
        // Camera ray (0.004, 0.004, 1).
        points.push(lidar_point(3.0, -0.012, -0.112));
        let background_pixel = {
            let mut alone = Fusion::new(config([0.0; 5])).expect("fusion");
            alone.fuse(&points[points.len() - 1..]).expect("fuse");
            alone.point_pixels()[0]
        };
        assert!(
            !points[..points.len() - 1].is_empty()
                && fusion.fuse(&points[..points.len() - 1]).is_ok()
                && !fusion.point_pixels().contains(&background_pixel)
        );
        let stats = fusion.fuse(&points).expect("fuse");
        assert_eq!(stats.occluded, 1, "{stats:?}");
        assert_eq!(fusion.fates().last(), Some(&PointFate::Occluded));
        assert_eq!(stats.visible, points.len() - 1);
    }

    #[test]
    fn noisy_returns_of_one_surface_are_averaged_not_culled() {
        use rand::{SeedableRng, rngs::SmallRng};
        use rand_distr::{Distribution, Normal};
        // A surface 1.5 m from the LiDAR sampled densely (several returns per pixel) with 2 cm
        // range noise.
        let sigma_m = 0.02;
        let noise = Normal::new(0.0, sigma_m).expect("sigma");
        let mut rng = SmallRng::seed_from_u64(7);
        let (mut points, mut exact) = (Vec::new(), Vec::new());
        for i in -20..=20 {
            for j in -20..=20 {
                let (y, z) = (0.001 * i as f64, -0.1 + 0.001 * j as f64);
                let scale = 1.5 / (1.5f64 * 1.5 + y * y + z * z).sqrt();
                exact.push(lidar_point(
                    (1.5 * scale) as f32,
                    (y * scale) as f32,
                    (z * scale) as f32,
                ));
                let range = 1.5 + noise.sample(&mut rng);
                let (y, z) = (0.001 * i as f64, -0.1 + 0.001 * j as f64);
                let scale = range / (1.5f64 * 1.5 + y * y + z * z).sqrt();
                points.push(lidar_point(
                    (1.5 * scale) as f32,
                    (y * scale) as f32,
                    (z * scale) as f32,
                ));
            }
        }
        let mean_depth = |fusion: &Fusion| {
            let depths: Vec<f32> = fusion
                .depth_m()
                .iter()
                .copied()
                .filter(|&z| z > 0.0)
                .collect();
            depths.iter().sum::<f32>() / depths.len() as f32
        };
        // The default 5 cm tolerance drops the far tail of the noise and pulls the depth in.
        let mut fixed = Fusion::new(config([0.0; 5])).expect("fusion");
        let stats = fixed.fuse(&points).expect("fuse");
        assert!(stats.occluded > points.len() / 50, "{stats:?}");
        // Sized by the range noise, no return of the one surface is culled and the pixels'
        // means are unbiased.
        let mut sized = Fusion::new(config([0.0; 5]).with_range_noise(sigma_m)).expect("fusion");
        let stats = sized.fuse(&points).expect("fuse");
        assert_eq!(stats.occluded, 0, "{stats:?}");
        assert!(
            stats.depth_pixels < stats.visible,
            "several returns per pixel: {stats:?}"
        );
        let mut noiseless = Fusion::new(config([0.0; 5])).expect("fusion");
        noiseless.fuse(&exact).expect("fuse");
        let truth = mean_depth(&noiseless);
        assert!(
            (mean_depth(&sized) - truth).abs() < 0.002,
            "{} vs {truth}",
            mean_depth(&sized)
        );
        assert!(mean_depth(&fixed) < mean_depth(&sized));
    }

    #[test]
    fn empty_and_all_nan_clouds_are_errors_and_reset_the_depth_image() {
        let mut fusion = Fusion::new(config([0.0; 5])).expect("fusion");
        fusion.fuse(&[lidar_point(2.0, 0.0, 0.1)]).expect("fuse");
        assert_eq!(fusion.depth_m().iter().filter(|&&z| z > 0.0).count(), 1);
        assert_eq!(fusion.fuse(&[]), Err(FusionError::EmptyCloud));
        assert!(fusion.depth_m().iter().all(|&z| z == 0.0));
        assert_eq!(
            fusion.fuse(&[lidar_point(f32::NAN, 1.0, 1.0)]),
            Err(FusionError::NoFinitePoint { points: 1 })
        );
    }

    #[test]
    fn depth_in_millimetres_matches_the_metric_image() {
        let mut fusion = Fusion::new(config([0.0; 5])).expect("fusion");
        fusion.fuse(&[lidar_point(1.2345, 0.0, 0.1)]).expect("fuse");
        let mut depth_mm = vec![9u16; 640 * 480];
        fusion.write_depth_mm(&mut depth_mm).expect("size");
        let nonzero: Vec<u16> = depth_mm.iter().copied().filter(|&d| d != 0).collect();
        assert_eq!(nonzero, vec![1235]);
        assert!(fusion.write_depth_mm(&mut depth_mm[..5]).is_err());
    }

    #[test]
    fn tof_depth_geometry_matches_fusion_into_colour_then_registration() {
        let meta = RgbdFrameMeta {
            color_from_depth: RigidTransform::from_translation([-0.025, 0.0, 0.0]),
            ..RgbdFrameMeta::default()
        };
        let camera_from_lidar = config([0.0; 5]).camera_from_lidar;
        let mut fusion =
            Fusion::new(FusionConfig::for_tof_depth(&meta, camera_from_lidar)).expect("fusion");
        fusion.fuse(&[lidar_point(2.0, 0.1, 0.05)]).expect("fuse");
        // The point in the depth camera frame: colour frame point moved by depth_from_color.
        let in_color = camera_from_lidar.apply([2.0, 0.1, 0.05]);
        let in_depth = meta.color_from_depth.inverse().apply(in_color);
        let (u, v) = meta.depth_intrinsics.project(in_depth).expect("front");
        let depth = fusion
            .depth_at_m(u.round() as usize, v.round() as usize)
            .expect("registered");
        assert!((f64::from(depth) - in_depth[2]).abs() < 1e-6);
        let mut depth_mm = vec![0u16; 640 * 480];
        fusion.write_depth_mm(&mut depth_mm).expect("size");
        assert_eq!(depth_mm.iter().filter(|&&d| d == 2000).count(), 1);
    }

    #[test]
    fn bad_setup_is_refused() {
        let mut bad = config([0.0; 5]);
        bad.camera_from_lidar.translation_m[0] = f64::NAN;
        assert!(matches!(Fusion::new(bad), Err(FusionError::Setup(_))));
        let mut bad = config([0.0; 5]);
        bad.intrinsics.fx_px = 0.0;
        assert!(Fusion::new(bad).is_err());
        // An image size from a frame's payload is bounded before any per-pixel allocation (a
        // perception property test's random geometry asked for 8.5e18 bytes).
        for (width_px, height_px) in [(u32::MAX, u32::MAX), (0, 480), (1921, 1080)] {
            let mut bad = config([0.0; 5]);
            bad.intrinsics.width_px = width_px;
            bad.intrinsics.height_px = height_px;
            assert!(
                matches!(Fusion::new(bad), Err(FusionError::Setup(_))),
                "{width_px}x{height_px}"
            );
        }
    }
}
