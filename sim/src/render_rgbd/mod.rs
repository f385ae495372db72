//! Rendering of the ToF camera's frames (Percipio TL460-S1-E1, [dual-arm sec. 2.1]) from the
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
//!
//! Layout: `camera` (one sensor's rays and z-buffer), `scene` (the world as primitives in a
//! camera's frame), `backdrop`, `raster` (band-wise rasterisation), `shader` (depth, owner and
//! label shaders), `color_shading` (RGB), `depth` (the depth frame and its noise), `label` and
//! `error`; the renderer itself is in this file.

mod backdrop;
mod camera;
mod color_shading;
mod depth;
mod error;
pub mod label;
mod raster;
mod scene;
mod shader;

pub use error::RenderError;

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};

use crate::orchard::{AppleId, World};
use crate::scenario::CameraConfig;
use backdrop::{Backdrop, BackdropKey, backdrop_pass};
use camera::RasterCamera;
use color_shading::Colors;
use raster::rasterize;
use scene::Scene;
use shader::Labels;

/// The apple a label belongs to, if it is an apple label.
pub fn apple_from_label(label: u32) -> Option<AppleId> {
    label.checked_sub(label::APPLE_BASE).map(AppleId)
}

type V3 = [f32; 3];

#[inline(always)]
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn to_f32(v: [f64; 3]) -> V3 {
    [v[0] as f32, v[1] as f32, v[2] as f32]
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

#[cfg(test)]
mod tests;
