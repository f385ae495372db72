//! Pinhole camera model with Brown-Conrady distortion, and rigid transforms.
//!
//! Conventions (used everywhere in the stack):
//! - Camera frame: x right, y down, z forward along the optical axis, metres.
//! - Pixel coordinates: `u` to the right, `v` down, origin at the centre of the top-left pixel.
//! - Distortion coefficients `[k1, k2, p1, p2, k3]` (OpenCV order) map undistorted normalized
//!   coordinates to distorted ones; [`CameraIntrinsics::undistort`] inverts that iteratively.
//! - Transforms are named `target_from_source`: `point_in_robot = robot_from_camera.apply(point_in_camera)`.

use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Intrinsic parameters of one camera (or of the LiDAR-camera projection).
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Describe,
)]
#[serde(deny_unknown_fields)]
pub struct CameraIntrinsics {
    /// Image width, pixels.
    pub width_px: u32,
    /// Image height, pixels.
    pub height_px: u32,
    /// Focal length along x, pixels.
    pub fx_px: f64,
    /// Focal length along y, pixels.
    pub fy_px: f64,
    /// Principal point x, pixels from the left edge.
    pub cx_px: f64,
    /// Principal point y, pixels from the top edge.
    pub cy_px: f64,
    /// `[k1, k2, p1, p2, k3]`.
    pub distortion: [f64; 5],
}

impl CameraIntrinsics {
    /// Ideal pinhole intrinsics from a horizontal field of view, square pixels, centred.
    pub fn from_horizontal_fov(width_px: u32, height_px: u32, horizontal_fov_deg: f64) -> Self {
        let fx_px = (width_px as f64 / 2.0) / (horizontal_fov_deg.to_radians() / 2.0).tan();
        Self {
            width_px,
            height_px,
            fx_px,
            fy_px: fx_px,
            cx_px: (width_px as f64 - 1.0) / 2.0,
            cy_px: (height_px as f64 - 1.0) / 2.0,
            distortion: [0.0; 5],
        }
    }

    /// The RGB camera of the Percipio TL460-S1-E1 as simulated: 1920x1080, 62 deg horizontal FOV,
    /// mild barrel distortion.
    pub fn tl460_rgb() -> Self {
        let mut intrinsics = Self::from_horizontal_fov(1920, 1080, 62.0);
        intrinsics.distortion = [-0.04, 0.01, 0.0, 0.0, 0.0];
        intrinsics
    }

    /// The ToF depth camera of the Percipio TL460-S1-E1 as simulated: 640x480, 62 x 49 deg FOV.
    pub fn tl460_depth() -> Self {
        let mut intrinsics = Self::from_horizontal_fov(640, 480, 62.0);
        intrinsics.fy_px = (240.0) / (49.0_f64.to_radians() / 2.0).tan();
        intrinsics
    }

    /// Applies the distortion model to undistorted normalized coordinates.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let r2 = x * x + y * y;
        let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
        let x_d = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
        let y_d = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
        (x_d, y_d)
    }

    /// Inverts [`Self::distort`] by fixed-point iteration (converges for realistic lenses).
    pub fn undistort(&self, x_d: f64, y_d: f64) -> (f64, f64) {
        if self.distortion == [0.0; 5] {
            return (x_d, y_d);
        }
        let (mut x, mut y) = (x_d, y_d);
        for _ in 0..20 {
            let (x_est, y_est) = self.distort(x, y);
            x += x_d - x_est;
            y += y_d - y_est;
        }
        (x, y)
    }

    /// Pixel -> undistorted normalized coordinates `(x/z, y/z)`.
    pub fn normalize(&self, u_px: f64, v_px: f64) -> (f64, f64) {
        let x_d = (u_px - self.cx_px) / self.fx_px;
        let y_d = (v_px - self.cy_px) / self.fy_px;
        self.undistort(x_d, y_d)
    }

    /// Undistorted normalized coordinates `(x/z, y/z)` of every pixel centre, row-major: the
    /// per-pixel ray table renderers and evaluators build once per camera.
    pub fn pixel_ray_table(&self) -> Vec<[f32; 2]> {
        let (width, height) = (self.width_px as usize, self.height_px as usize);
        let mut rays = Vec::with_capacity(width * height);
        for v in 0..height {
            for u in 0..width {
                let (x, y) = self.normalize(u as f64, v as f64);
                rays.push([x as f32, y as f32]);
            }
        }
        rays
    }

    /// Undistorted normalized coordinates -> pixel.
    pub fn denormalize(&self, x: f64, y: f64) -> (f64, f64) {
        let (x_d, y_d) = self.distort(x, y);
        (self.fx_px * x_d + self.cx_px, self.fy_px * y_d + self.cy_px)
    }

    /// Projects a point in the camera frame (metres) to a pixel; `None` behind the camera.
    pub fn project(&self, point_in_camera: [f64; 3]) -> Option<(f64, f64)> {
        let [x, y, z] = point_in_camera;
        if z <= 1e-9 || !x.is_finite() || !y.is_finite() || !z.is_finite() {
            return None;
        }
        Some(self.denormalize(x / z, y / z))
    }

    /// Back-projects a pixel with its depth (z, metres) to a point in the camera frame.
    pub fn unproject(&self, u_px: f64, v_px: f64, depth_m: f64) -> [f64; 3] {
        let (x, y) = self.normalize(u_px, v_px);
        [x * depth_m, y * depth_m, depth_m]
    }

    /// What makes these intrinsics unusable (an empty image, a focal length that is not a
    /// positive number, a non-finite principal point or distortion coefficient), naming the key
    /// and value; `None` when they describe a camera.
    pub fn problem(&self) -> Option<String> {
        if self.width_px == 0 || self.height_px == 0 {
            return Some(format!(
                "intrinsics size {} x {} px is empty",
                self.width_px, self.height_px
            ));
        }
        for (key, value) in [("fx_px", self.fx_px), ("fy_px", self.fy_px)] {
            if !(value.is_finite() && value > 0.0) {
                return Some(format!("intrinsics {key} = {value} is not positive"));
            }
        }
        for (key, value) in [("cx_px", self.cx_px), ("cy_px", self.cy_px)] {
            if !value.is_finite() {
                return Some(format!("intrinsics {key} = {value} is not finite"));
            }
        }
        if !self.distortion.iter().all(|c| c.is_finite()) {
            return Some(format!(
                "intrinsics distortion = {:?} is not finite",
                self.distortion
            ));
        }
        None
    }

    /// True when the pixel lies inside the image.
    pub fn contains(&self, u_px: f64, v_px: f64) -> bool {
        u_px >= -0.5
            && v_px >= -0.5
            && u_px < self.width_px as f64 - 0.5
            && v_px < self.height_px as f64 - 0.5
    }
}

/// A rigid transform `target_from_source`: rotation (row-major) then translation in metres.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Describe,
)]
#[serde(deny_unknown_fields)]
pub struct RigidTransform {
    /// Rotation matrix, row-major (`rotation[row][column]`).
    pub rotation: [[f64; 3]; 3],
    /// Translation, metres, applied after the rotation.
    pub translation_m: [f64; 3],
}

impl Default for RigidTransform {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl RigidTransform {
    /// The transform that changes nothing.
    pub const IDENTITY: Self = Self {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation_m: [0.0; 3],
    };

    /// True when every entry is finite and the rotation is proper: orthonormal rows (to 1e-6)
    /// and determinant +1.
    pub fn is_rigid(&self) -> bool {
        let r = &self.rotation;
        let finite = r
            .iter()
            .flatten()
            .chain(&self.translation_m)
            .all(|v| v.is_finite());
        let orthonormal = (0..3).all(|i| {
            (0..3).all(|j| {
                let dot: f64 = (0..3).map(|k| r[i][k] * r[j][k]).sum();
                (dot - if i == j { 1.0 } else { 0.0 }).abs() < 1e-6
            })
        });
        let determinant = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        finite && orthonormal && determinant > 0.0
    }

    /// A pure translation.
    pub fn from_translation(translation_m: [f64; 3]) -> Self {
        Self {
            translation_m,
            ..Self::IDENTITY
        }
    }

    /// Rotation from roll (x), pitch (y), yaw (z) in radians, applied as `Rz * Ry * Rx`.
    pub fn from_rpy_translation(
        roll_rad: f64,
        pitch_rad: f64,
        yaw_rad: f64,
        translation_m: [f64; 3],
    ) -> Self {
        let (sr, cr) = roll_rad.sin_cos();
        let (sp, cp) = pitch_rad.sin_cos();
        let (sy, cy) = yaw_rad.sin_cos();
        let rotation = [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ];
        Self {
            rotation,
            translation_m,
        }
    }

    /// `self * point`.
    pub fn apply(&self, point: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let t = &self.translation_m;
        [
            r[0][0] * point[0] + r[0][1] * point[1] + r[0][2] * point[2] + t[0],
            r[1][0] * point[0] + r[1][1] * point[1] + r[1][2] * point[2] + t[1],
            r[2][0] * point[0] + r[2][1] * point[1] + r[2][2] * point[2] + t[2],
        ]
    }

    /// Rotates a direction (no translation).
    pub fn rotate(&self, vector: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [
            r[0][0] * vector[0] + r[0][1] * vector[1] + r[0][2] * vector[2],
            r[1][0] * vector[0] + r[1][1] * vector[1] + r[1][2] * vector[2],
            r[2][0] * vector[0] + r[2][1] * vector[1] + r[2][2] * vector[2],
        ]
    }

    /// `source_from_target` for `self = target_from_source`.
    pub fn inverse(&self) -> Self {
        let r = &self.rotation;
        let rotation = [
            [r[0][0], r[1][0], r[2][0]],
            [r[0][1], r[1][1], r[2][1]],
            [r[0][2], r[1][2], r[2][2]],
        ];
        let inverse = Self {
            rotation,
            translation_m: [0.0; 3],
        };
        let t = inverse.rotate(self.translation_m);
        Self {
            rotation,
            translation_m: [-t[0], -t[1], -t[2]],
        }
    }

    /// `a_from_c = a_from_b.then(b_from_c)`, i.e. matrix product `self * other`.
    pub fn compose(&self, other: &Self) -> Self {
        let mut rotation = [[0.0; 3]; 3];
        for (i, row) in rotation.iter_mut().enumerate() {
            for (j, cell) in row.iter_mut().enumerate() {
                *cell = (0..3)
                    .map(|k| self.rotation[i][k] * other.rotation[k][j])
                    .sum();
            }
        }
        Self {
            rotation,
            translation_m: self.apply(other.translation_m),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unusable_intrinsics_and_improper_rotations_are_named() {
        assert_eq!(CameraIntrinsics::tl460_rgb().problem(), None);
        let mut k = CameraIntrinsics::tl460_rgb();
        k.fy_px = -1.0;
        assert_eq!(
            k.problem().as_deref(),
            Some("intrinsics fy_px = -1 is not positive")
        );
        k = CameraIntrinsics::tl460_rgb();
        k.height_px = 0;
        assert!(k.problem().is_some_and(|p| p.contains("is empty")));
        k = CameraIntrinsics::tl460_rgb();
        k.distortion[4] = f64::NAN;
        assert!(k.problem().is_some_and(|p| p.contains("distortion")));

        let pose = RigidTransform::from_rpy_translation(0.1, -0.2, 0.3, [1.0, 2.0, 3.0]);
        assert!(pose.is_rigid());
        let mut mirrored = pose;
        mirrored.rotation[2] = mirrored.rotation[2].map(|v| -v);
        assert!(!mirrored.is_rigid(), "a reflection is not a rotation");
        let mut skewed = pose;
        skewed.rotation[0][1] += 0.01;
        assert!(!skewed.is_rigid());
        let mut nan = pose;
        nan.translation_m[1] = f64::NAN;
        assert!(!nan.is_rigid());
    }

    #[test]
    fn project_unproject_round_trip_with_distortion() {
        let intrinsics = CameraIntrinsics::tl460_rgb();
        let point = [0.21, -0.13, 1.2];
        let (u, v) = intrinsics.project(point).expect("in front");
        let back = intrinsics.unproject(u, v, point[2]);
        for axis in 0..3 {
            assert!(
                (back[axis] - point[axis]).abs() < 1e-9,
                "{back:?} vs {point:?}"
            );
        }
    }

    #[test]
    fn transform_inverse_composes_to_identity() {
        let robot_from_camera =
            RigidTransform::from_rpy_translation(0.1, -0.2, 0.3, [0.5, -1.0, 0.2]);
        let identity = robot_from_camera.compose(&robot_from_camera.inverse());
        for i in 0..3 {
            for j in 0..3 {
                let expected = if i == j { 1.0 } else { 0.0 };
                assert!((identity.rotation[i][j] - expected).abs() < 1e-12);
            }
            assert!(identity.translation_m[i].abs() < 1e-12);
        }
    }
}
