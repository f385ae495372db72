//! One sensor of the ToF camera as the rasteriser sees it: intrinsics, pose, the per-pixel ray
//! table and z-buffer, and the pixel boxes that bound an object's projection.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};

use super::backdrop::BackdropCache;

/// Objects closer to the camera than this (z, metres) are not drawn.
pub(super) const NEAR_M: f64 = 0.05;

/// Inclusive pixel rectangle.
#[derive(Debug, Clone, Copy)]
pub(super) struct PixelBox {
    pub(super) u0: usize,
    pub(super) u1: usize,
    pub(super) v0: usize,
    pub(super) v1: usize,
}

/// One sensor: intrinsics, pose, per-pixel rays and z-buffer.
#[derive(Debug)]
pub(super) struct RasterCamera {
    pub(super) intrinsics: CameraIntrinsics,
    pub(super) camera_from_robot: RigidTransform,
    pub(super) robot_from_camera: RigidTransform,
    pub(super) width: usize,
    pub(super) height: usize,
    /// Undistorted normalised coordinates `(x/z, y/z)` of every pixel centre, row-major.
    pub(super) rays: Vec<[f32; 2]>,
    /// Depth (z, metres) of the nearest surface so far; infinity = nothing.
    pub(super) z_m: Vec<f32>,
    /// The static backdrop as this camera sees it.
    pub(super) backdrop: BackdropCache,
}

impl RasterCamera {
    pub(super) fn new(intrinsics: CameraIntrinsics, robot_from_camera: RigidTransform) -> Self {
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
    pub(super) fn pixel_box(&self, x0: f64, x1: f64, y0: f64, y1: f64) -> Option<PixelBox> {
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
    pub(super) fn hull_box(&self, corners: &[[f64; 3]]) -> Option<PixelBox> {
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
