//! Renders what the ALACS camera sees: shaded apples and leaves, and the red laser stripe where
//! the laser plane (paper eq. 4-5, slide position `d`) meets the nearest surface the laser can
//! reach. Pure computation, no I/O: the simulator and the in-process unit call it.
//!
//! Image model, per pixel: albedo x Lambert shading (+ ambient), plus the laser colour times a
//! Gaussian profile across the stripe times the surface's red reflectance, plus optional
//! Gaussian sensor noise, rounded and clamped to 8 bits (the stripe saturates on bright red
//! apples, as a real laser does). The stripe centre in each row is the exact sub-pixel crossing
//! of the laser plane on that row's surface, so extraction accuracy can be checked against it.

use harvest_ipc::camera_model::CameraIntrinsics;
use rand::SeedableRng;
use rand::rngs::SmallRng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::alacs::scene::{AlacsScene, SurfaceId, dot, norm, sub};
use harvest_hw::alacs::AlacsError;
use harvest_hw::alacs::extrinsics::{AlacsExtrinsics, check_slide_position};

/// How the laser and the sensor look in the image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaserRenderParams {
    /// Laser powered; when off only the scene is rendered.
    pub laser_on: bool,
    /// Standard deviation of the stripe's Gaussian profile across the stripe, pixels.
    pub stripe_sigma_px: f64,
    /// Digital numbers added per channel at the stripe centre on a white surface (the red
    /// laser also lifts green and blue a little as the sensor blooms).
    pub laser_gain_dn: [f64; 3],
    /// Standard deviation of additive Gaussian sensor noise per channel, digital numbers;
    /// 0 for a noise-free image.
    pub noise_sigma_dn: f64,
    /// Seed of the noise; the same seed gives the same image.
    pub noise_seed: u64,
}

impl Default for LaserRenderParams {
    fn default() -> Self {
        Self {
            laser_on: true,
            stripe_sigma_px: 1.5,
            laser_gain_dn: [230.0, 70.0, 50.0],
            noise_sigma_dn: 2.0,
            noise_seed: 0,
        }
    }
}

/// What one render produced.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RenderStats {
    /// Row crossings of the laser plane on a surface the laser reaches (stripe samples drawn).
    pub lit_crossings: usize,
    /// Row crossings hidden from the laser by another object (laser shadow).
    pub shadowed_crossings: usize,
}

/// Stripe profile cut-off, in standard deviations.
const STRIPE_HALF_WIDTH_SIGMAS: f64 = 3.0;
/// Distance below which a laser ray reaching a surface point counts as reaching it, metres.
const LASER_REACH_TOLERANCE_M: f64 = 1e-4;

/// A renderer bound to one camera: caches each pixel's undistorted ray (eq. 3) so a frame costs
/// ray casting only. Build one per camera and reuse it for every frame.
#[derive(Debug, Clone)]
pub struct AlacsRenderer {
    intrinsics: CameraIntrinsics,
    /// Undistorted normalised coordinates `(u_bar, v_bar)` of every pixel, row-major.
    rays: Vec<[f64; 2]>,
}

impl AlacsRenderer {
    /// Precomputes the rays of `intrinsics` (allocates `width x height x 16` bytes).
    pub fn new(intrinsics: CameraIntrinsics) -> Result<Self, AlacsError> {
        let finite = [
            intrinsics.fx_px,
            intrinsics.fy_px,
            intrinsics.cx_px,
            intrinsics.cy_px,
        ]
        .iter()
        .chain(intrinsics.distortion.iter())
        .all(|value| value.is_finite());
        if intrinsics.width_px == 0
            || intrinsics.height_px == 0
            || !finite
            || intrinsics.fx_px <= 0.0
            || intrinsics.fy_px <= 0.0
        {
            return Err(AlacsError::InvalidInput {
                what: format!("intrinsics = {intrinsics:?}"),
            });
        }
        let mut rays =
            Vec::with_capacity(intrinsics.width_px as usize * intrinsics.height_px as usize);
        for v in 0..intrinsics.height_px {
            for u in 0..intrinsics.width_px {
                let (u_bar, v_bar) = intrinsics.normalize(f64::from(u), f64::from(v));
                rays.push([u_bar, v_bar]);
            }
        }
        Ok(Self { intrinsics, rays })
    }

    pub fn intrinsics(&self) -> &CameraIntrinsics {
        &self.intrinsics
    }

    /// Bytes of one RGB8 image of this camera.
    pub fn image_len(&self) -> usize {
        self.rays.len() * 3
    }

    /// Renders the scene with the laser at slide position `slide_position_m` into `rgb`
    /// (row-major RGB8, exactly [`Self::image_len`] bytes).
    ///
    /// Fails with kind `InvalidRequest` (nothing written) when the slide position is outside
    /// the stroke, the buffer has the wrong size, or an input is not finite.
    pub fn render(
        &self,
        extrinsics: &AlacsExtrinsics,
        slide_position_m: f64,
        scene: &AlacsScene,
        params: &LaserRenderParams,
        rgb: &mut [u8],
    ) -> Result<RenderStats, AlacsError> {
        check_slide_position(slide_position_m)?;
        if rgb.len() != self.image_len() {
            return Err(AlacsError::BufferSize {
                got_bytes: rgb.len(),
                needed_bytes: self.image_len(),
                width_px: self.intrinsics.width_px,
                height_px: self.intrinsics.height_px,
            });
        }
        if !extrinsics.is_valid() {
            return Err(AlacsError::InvalidInput {
                what: format!("extrinsics = {extrinsics:?}"),
            });
        }
        validate_params(params)?;
        scene.validate()?;
        let noise = if params.noise_sigma_dn > 0.0 {
            Normal::new(0.0, params.noise_sigma_dn).ok()
        } else {
            None
        };
        let mut rng = SmallRng::seed_from_u64(params.noise_seed);

        let plane = extrinsics.laser_plane_in_camera(slide_position_m);
        let laser_origin = extrinsics.camera_from_laser(slide_position_m).translation_m;
        let laser_axis = extrinsics.laser_axis_in_camera();
        let width = self.intrinsics.width_px as usize;
        let half_width_px = STRIPE_HALF_WIDTH_SIGMAS * params.stripe_sigma_px;
        let inverse_two_variance = 1.0 / (2.0 * params.stripe_sigma_px * params.stripe_sigma_px);

        let mut row: Vec<PixelSample> = vec![PixelSample::EMPTY; width];
        let mut laser_weight: Vec<f64> = vec![0.0; width];
        let mut stats = RenderStats::default();
        for (row_rays, row_rgb) in self
            .rays
            .chunks_exact(width)
            .zip(rgb.chunks_exact_mut(width * 3))
        {
            for (sample, ray) in row.iter_mut().zip(row_rays) {
                *sample = match scene.ray_cast([0.0; 3], [ray[0], ray[1], 1.0]) {
                    Some(hit) => {
                        let shade = scene.shading(hit.normal);
                        PixelSample {
                            surface: Some(hit.surface),
                            point_in_camera_m: hit.point_in_camera_m,
                            plane_distance_m: plane.signed_distance_m(hit.point_in_camera_m),
                            base_dn: hit.albedo_rgb.map(|c| f64::from(c) * shade),
                            laser_reflectance: 0.3 + 0.7 * f64::from(hit.albedo_rgb[0]) / 255.0,
                        }
                    }
                    None => PixelSample {
                        base_dn: scene.background_rgb.map(f64::from),
                        ..PixelSample::EMPTY
                    },
                };
            }

            laser_weight.fill(0.0);
            if params.laser_on {
                for u in 0..width.saturating_sub(1) {
                    let (left, right) = (&row[u], &row[u + 1]);
                    let Some(surface) = left.surface else {
                        continue;
                    };
                    if right.surface != Some(surface)
                        || (left.plane_distance_m < 0.0) == (right.plane_distance_m < 0.0)
                    {
                        continue;
                    }
                    let fraction =
                        left.plane_distance_m / (left.plane_distance_m - right.plane_distance_m);
                    let point = lerp(left.point_in_camera_m, right.point_in_camera_m, fraction);
                    if !laser_reaches(scene, laser_origin, laser_axis, point, surface) {
                        stats.shadowed_crossings += 1;
                        continue;
                    }
                    stats.lit_crossings += 1;
                    let centre_px = u as f64 + fraction;
                    let first = (centre_px - half_width_px).ceil().max(0.0) as usize;
                    let last = ((centre_px + half_width_px).floor() as usize).min(width - 1);
                    for (k, weight) in laser_weight
                        .iter_mut()
                        .enumerate()
                        .take(last + 1)
                        .skip(first)
                    {
                        if row[k].surface == Some(surface) {
                            let offset_px = k as f64 - centre_px;
                            *weight += (-offset_px * offset_px * inverse_two_variance).exp();
                        }
                    }
                }
            }

            for ((sample, weight), pixel) in row
                .iter()
                .zip(&laser_weight)
                .zip(row_rgb.chunks_exact_mut(3))
            {
                let laser = weight.min(1.0) * sample.laser_reflectance;
                for ((out, base_dn), gain_dn) in pixel
                    .iter_mut()
                    .zip(sample.base_dn)
                    .zip(params.laser_gain_dn)
                {
                    let mut value = base_dn + laser * gain_dn;
                    if let Some(noise) = &noise {
                        value += noise.sample(&mut rng);
                    }
                    *out = value.round().clamp(0.0, 255.0) as u8;
                }
            }
        }
        Ok(stats)
    }
}

/// Renders one frame without keeping a renderer (recomputes every pixel's ray, so prefer
/// [`AlacsRenderer`] for a stream of frames). Same contract as [`AlacsRenderer::render`].
pub fn render_laser_line(
    intrinsics: &CameraIntrinsics,
    extrinsics: &AlacsExtrinsics,
    slide_position_m: f64,
    scene: &AlacsScene,
    params: &LaserRenderParams,
    rgb: &mut [u8],
) -> Result<RenderStats, AlacsError> {
    check_slide_position(slide_position_m)?;
    AlacsRenderer::new(*intrinsics)?.render(extrinsics, slide_position_m, scene, params, rgb)
}

/// One pixel's surface while a row is rendered.
#[derive(Debug, Clone, Copy)]
struct PixelSample {
    surface: Option<SurfaceId>,
    point_in_camera_m: [f64; 3],
    plane_distance_m: f64,
    base_dn: [f64; 3],
    /// Share of the laser light the surface sends back (red albedo; leaves absorb red).
    laser_reflectance: f64,
}

impl PixelSample {
    const EMPTY: Self = Self {
        surface: None,
        point_in_camera_m: [0.0; 3],
        plane_distance_m: 0.0,
        base_dn: [0.0; 3],
        laser_reflectance: 0.0,
    };
}

fn validate_params(params: &LaserRenderParams) -> Result<(), AlacsError> {
    let invalid = |what: String| Err(AlacsError::InvalidInput { what });
    if !(params.stripe_sigma_px.is_finite() && params.stripe_sigma_px > 0.0) {
        return invalid(format!("stripe_sigma_px = {}", params.stripe_sigma_px));
    }
    if !params
        .laser_gain_dn
        .iter()
        .all(|g| g.is_finite() && *g >= 0.0)
    {
        return invalid(format!("laser_gain_dn = {:?}", params.laser_gain_dn));
    }
    if !(params.noise_sigma_dn.is_finite() && params.noise_sigma_dn >= 0.0) {
        return invalid(format!("noise_sigma_dn = {}", params.noise_sigma_dn));
    }
    Ok(())
}

/// True when the laser, emitting forward from `laser_origin` along `laser_axis`, reaches
/// `point` on `surface` before any other object (no laser shadow).
fn laser_reaches(
    scene: &AlacsScene,
    laser_origin: [f64; 3],
    laser_axis: [f64; 3],
    point: [f64; 3],
    surface: SurfaceId,
) -> bool {
    let to_point = sub(point, laser_origin);
    if dot(to_point, laser_axis) <= 0.0 {
        return false;
    }
    let distance_m = norm(to_point);
    let direction = to_point.map(|c| c / distance_m);
    scene.ray_cast(laser_origin, direction).is_some_and(|hit| {
        hit.surface == surface && (hit.t - distance_m).abs() < LASER_REACH_TOLERANCE_M
    })
}

fn lerp(a: [f64; 3], b: [f64; 3], fraction: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * fraction,
        a[1] + (b[1] - a[1]) * fraction,
        a[2] + (b[2] - a[2]) * fraction,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::alacs::scene::{AppleSphere, LeafDisc};
    use harvest_hw::error_kind::{DeviceError, ErrorKind};

    fn small_camera() -> CameraIntrinsics {
        let mut intrinsics = CameraIntrinsics::from_horizontal_fov(320, 240, 45.0);
        intrinsics.distortion = [-0.05, 0.01, 0.0, 0.0, 0.0];
        intrinsics
    }

    fn apple_on_plane(
        extrinsics: &AlacsExtrinsics,
        slide_position_m: f64,
        depth_m: f64,
    ) -> AppleSphere {
        // Centre 1 cm right of the laser plane at this depth (line on the apple's left half).
        let (sin_a, cos_a) = extrinsics.alpha_rad.sin_cos();
        let x_on_plane = (depth_m * sin_a - extrinsics.baseline_m(slide_position_m)) / cos_a;
        AppleSphere {
            centre_in_camera_m: [x_on_plane + 0.01, 0.0, depth_m],
            radius_m: 0.04,
            rgb: [150, 30, 25],
        }
    }

    #[test]
    fn stripe_is_drawn_where_the_plane_crosses_the_apple() {
        let intrinsics = small_camera();
        let renderer = AlacsRenderer::new(intrinsics).expect("renderer");
        let extrinsics = AlacsExtrinsics::paper_table1();
        let slide_position_m = 0.1;
        let scene = AlacsScene {
            apples: vec![apple_on_plane(&extrinsics, slide_position_m, 0.8)],
            ..AlacsScene::default()
        };
        let params = LaserRenderParams {
            noise_sigma_dn: 0.0,
            ..LaserRenderParams::default()
        };
        let mut rgb = vec![0; renderer.image_len()];
        let stats = renderer
            .render(&extrinsics, slide_position_m, &scene, &params, &mut rgb)
            .expect("render");
        assert!(stats.lit_crossings > 20, "{stats:?}");
        // In the apple's middle row the brightest red pixel sits on the laser plane.
        let plane = extrinsics.laser_plane_in_camera(slide_position_m);
        let centre = scene.apples[0].centre_in_camera_m;
        let (_, v_centre) = intrinsics.project(centre).expect("visible");
        let v = v_centre.round() as usize;
        let width = intrinsics.width_px as usize;
        let row = &rgb[v * width * 3..(v + 1) * width * 3];
        let brightest_u = (0..width)
            .max_by_key(|u| u32::from(row[u * 3]) * 4 - u32::from(row[u * 3 + 1]))
            .expect("row");
        let (u_bar, v_bar) = intrinsics.normalize(brightest_u as f64, v as f64);
        let hit = scene
            .ray_cast([0.0; 3], [u_bar, v_bar, 1.0])
            .expect("on the apple");
        assert_eq!(hit.surface, SurfaceId::Apple(0));
        let pixel_size_m = hit.point_in_camera_m[2] / intrinsics.fx_px;
        assert!(plane.signed_distance_m(hit.point_in_camera_m).abs() < 2.0 * pixel_size_m);
        // Laser off: no saturated red anywhere.
        let off = LaserRenderParams {
            laser_on: false,
            ..params
        };
        renderer
            .render(&extrinsics, slide_position_m, &scene, &off, &mut rgb)
            .expect("render");
        assert!(rgb.chunks_exact(3).all(|p| p[0] < 200));
    }

    #[test]
    fn a_leaf_between_laser_and_apple_casts_a_laser_shadow() {
        let intrinsics = small_camera();
        let renderer = AlacsRenderer::new(intrinsics).expect("renderer");
        let extrinsics = AlacsExtrinsics::paper_table1();
        let apple = apple_on_plane(&extrinsics, 0.0, 0.9);
        let clear = AlacsScene {
            apples: vec![apple],
            ..AlacsScene::default()
        };
        // A leaf on the laser's path, a quarter of the way from emitter to apple, outside the
        // camera's field of view: it blocks the laser, not the camera.
        let laser_origin = extrinsics.camera_from_laser(0.0).translation_m;
        let midway = lerp(laser_origin, apple.centre_in_camera_m, 0.25);
        let shadowed = AlacsScene {
            leaves: vec![LeafDisc {
                centre_in_camera_m: midway,
                normal: [1.0, 0.0, 0.0],
                radius_m: 0.1,
                rgb: [50, 110, 40],
            }],
            ..clear.clone()
        };
        let params = LaserRenderParams::default();
        let mut rgb = vec![0; renderer.image_len()];
        let lit = renderer
            .render(&extrinsics, 0.0, &clear, &params, &mut rgb)
            .expect("render");
        let dark = renderer
            .render(&extrinsics, 0.0, &shadowed, &params, &mut rgb)
            .expect("render");
        assert!(lit.lit_crossings > 0);
        assert_eq!(dark.lit_crossings, 0, "{dark:?}");
        assert!(dark.shadowed_crossings > 0);
    }

    #[test]
    fn bad_requests_write_nothing() {
        let intrinsics = small_camera();
        let renderer = AlacsRenderer::new(intrinsics).expect("renderer");
        let extrinsics = AlacsExtrinsics::paper_table1();
        let scene = AlacsScene::default();
        let params = LaserRenderParams::default();
        let mut rgb = vec![7; renderer.image_len()];
        let error = renderer
            .render(&extrinsics, 0.25, &scene, &params, &mut rgb)
            .expect_err("outside stroke");
        assert_eq!(error.kind(), ErrorKind::InvalidRequest);
        let mut short = vec![7; 10];
        let error = renderer
            .render(&extrinsics, 0.1, &scene, &params, &mut short)
            .expect_err("short buffer");
        assert!(matches!(error, AlacsError::BufferSize { .. }));
        let bad_params = LaserRenderParams {
            stripe_sigma_px: f64::NAN,
            ..params
        };
        assert!(
            renderer
                .render(&extrinsics, 0.1, &scene, &bad_params, &mut rgb)
                .is_err()
        );
        assert!(rgb.iter().all(|&b| b == 7));
    }

    #[test]
    fn same_seed_same_image() {
        let intrinsics = CameraIntrinsics::from_horizontal_fov(64, 48, 45.0);
        let extrinsics = AlacsExtrinsics::paper_table1();
        let scene = AlacsScene::default();
        let params = LaserRenderParams::default();
        let mut first = vec![0; 64 * 48 * 3];
        let mut second = vec![0; 64 * 48 * 3];
        render_laser_line(&intrinsics, &extrinsics, 0.0, &scene, &params, &mut first)
            .expect("render");
        render_laser_line(&intrinsics, &extrinsics, 0.0, &scene, &params, &mut second)
            .expect("render");
        assert_eq!(first, second);
    }
}
