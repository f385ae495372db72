//! Depth-to-colour registration: which colour pixel every depth sample lands on, and where it is
//! in the colour camera frame.
//!
//! For depth pixel `(u_d, v_d)` with z-depth `z_d` (ToF z-depth, mm -> m):
//! `p_depth = z_d * (x_n, y_n, 1)` with `(x_n, y_n)` the undistorted normalized coordinates of
//! the depth camera, `p_color = color_from_depth.apply(p_depth)`, and the colour pixel is
//! `color.project(p_color)` (pinhole + Brown-Conrady, `harvest_ipc::camera_model`). This is the
//! per-fruit mask-point extraction of [dual-arm sec. 3.1.3] and of [fusion eq. 1-2] (projection),
//! with the depth camera in the LiDAR's place.
//!
//! The rotated rays `R * (x_n, y_n, 1)` are computed once per camera rig, so each sample costs a
//! multiply-add and one projection.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::frame::{DepthView, FrameError};

/// Accepted depth interval in millimetres (TL460 working range 0.3-9.5 m).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthRange {
    pub min_mm: u16,
    pub max_mm: u16,
}

impl Default for DepthRange {
    fn default() -> Self {
        Self {
            min_mm: 300,
            max_mm: 9500,
        }
    }
}

/// A [`DepthRange`] that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DepthRangeError {
    /// The range is empty or starts at 0 (0 means "no return").
    #[error("depth range {min_mm}..={max_mm} mm is empty or starts at 0")]
    Empty { min_mm: u16, max_mm: u16 },
}

impl DepthRange {
    pub fn validate(&self) -> Result<(), DepthRangeError> {
        if self.min_mm == 0 || self.min_mm > self.max_mm {
            return Err(DepthRangeError::Empty {
                min_mm: self.min_mm,
                max_mm: self.max_mm,
            });
        }
        Ok(())
    }
}

/// One depth sample expressed in the colour camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegisteredPoint {
    /// Index of the depth pixel (`v * width + u`).
    pub depth_index: usize,
    /// Position in the colour camera frame, metres.
    pub point_in_camera_m: [f64; 3],
    /// Colour pixel the point projects to.
    pub u_px: f64,
    pub v_px: f64,
}

/// Per-frame counts of the registration pass.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RegistrationCounts {
    /// Samples in range that project inside the colour image.
    pub registered: u32,
    /// Samples equal to 0 (no return).
    pub zero: u32,
    /// Non-zero samples outside the accepted depth range.
    pub out_of_range: u32,
    /// Valid samples that land outside the colour image (or behind the colour camera).
    pub outside_color: u32,
}

/// Precomputed depth-to-colour mapping for one camera rig.
#[derive(Debug, Clone)]
pub struct DepthRegistration {
    depth: CameraIntrinsics,
    color: CameraIntrinsics,
    color_from_depth: RigidTransform,
    range: DepthRange,
    /// `R_color_from_depth * (x_n, y_n, 1)` per depth pixel.
    rotated_rays: Vec<[f32; 3]>,
}

impl DepthRegistration {
    /// Builds the ray table (`depth.width_px * depth.height_px` entries). The caller validates
    /// the camera parameters ([`crate::camera_setup::CameraSetup::validate`]).
    pub fn new(
        depth: CameraIntrinsics,
        color: CameraIntrinsics,
        color_from_depth: RigidTransform,
        range: DepthRange,
    ) -> Self {
        let mut rotated_rays =
            Vec::with_capacity(depth.width_px as usize * depth.height_px as usize);
        for v in 0..depth.height_px {
            for u in 0..depth.width_px {
                let (x_n, y_n) = depth.normalize(u as f64, v as f64);
                let ray = color_from_depth.rotate([x_n, y_n, 1.0]);
                rotated_rays.push([ray[0] as f32, ray[1] as f32, ray[2] as f32]);
            }
        }
        Self {
            depth,
            color,
            color_from_depth,
            range,
            rotated_rays,
        }
    }

    pub fn depth_intrinsics(&self) -> &CameraIntrinsics {
        &self.depth
    }

    pub fn color_intrinsics(&self) -> &CameraIntrinsics {
        &self.color
    }

    /// Registers one depth sample; `None` for no return, out of range, or off the colour image.
    pub fn register_sample(&self, depth_index: usize, depth_mm: u16) -> Option<RegisteredPoint> {
        if depth_mm < self.range.min_mm || depth_mm > self.range.max_mm {
            return None;
        }
        let ray = self.rotated_rays.get(depth_index)?;
        self.project_ray(depth_index, ray, depth_mm)
    }

    fn project_ray(
        &self,
        depth_index: usize,
        ray: &[f32; 3],
        depth_mm: u16,
    ) -> Option<RegisteredPoint> {
        let z_m = f64::from(depth_mm) * 1e-3;
        let t = &self.color_from_depth.translation_m;
        let point = [
            z_m * f64::from(ray[0]) + t[0],
            z_m * f64::from(ray[1]) + t[1],
            z_m * f64::from(ray[2]) + t[2],
        ];
        let (u_px, v_px) = self.color.project(point)?;
        if !self.color.contains(u_px, v_px) {
            return None;
        }
        Some(RegisteredPoint {
            depth_index,
            point_in_camera_m: point,
            u_px,
            v_px,
        })
    }

    /// Calls `visit` for every valid depth sample that lands in the colour image, in raster
    /// order. Fails (without visiting) when the frame does not match the depth camera.
    pub fn register(
        &self,
        depth: &DepthView<'_>,
        mut visit: impl FnMut(&RegisteredPoint),
    ) -> Result<RegistrationCounts, FrameError> {
        depth.validate_size(self.depth.width_px, self.depth.height_px)?;
        let mut counts = RegistrationCounts::default();
        for (index, (&depth_mm, ray)) in depth.data.iter().zip(self.rotated_rays.iter()).enumerate()
        {
            if depth_mm == 0 {
                counts.zero += 1;
                continue;
            }
            if depth_mm < self.range.min_mm || depth_mm > self.range.max_mm {
                counts.out_of_range += 1;
                continue;
            }
            match self.project_ray(index, ray, depth_mm) {
                Some(point) => {
                    counts.registered += 1;
                    visit(&point);
                }
                None => counts.outside_color += 1,
            }
        }
        Ok(counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera_setup::CameraSetup;

    #[test]
    fn registered_point_reprojects_onto_the_colour_pixel_of_the_true_point() {
        let setup = CameraSetup::tl460_simulated(RigidTransform::IDENTITY);
        let registration = DepthRegistration::new(
            setup.depth,
            setup.color,
            setup.color_from_depth,
            DepthRange::default(),
        );
        // A point 1.2 m ahead, seen by the depth camera at some pixel.
        let true_in_color = [0.11, -0.07, 1.2];
        let depth_from_color = setup.color_from_depth.inverse();
        let in_depth = depth_from_color.apply(true_in_color);
        let (u_d, v_d) = setup.depth.project(in_depth).expect("in front");
        let (u_i, v_i) = (u_d.round() as usize, v_d.round() as usize);
        let index = v_i * setup.depth.width_px as usize + u_i;
        // Depth of the pixel-centre ray at the same z.
        let depth_mm = (in_depth[2] * 1000.0).round() as u16;
        let point = registration
            .register_sample(index, depth_mm)
            .expect("registered");
        // The pixel centre differs from the true sub-pixel position by < 0.5 depth px, i.e.
        // < 0.5 * z / fx metres laterally; depth rounding adds < 0.5 mm.
        let lateral_tolerance_m = 0.5 * in_depth[2] / setup.depth.fx_px * 1.5 + 0.001;
        for axis in 0..3 {
            assert!(
                (point.point_in_camera_m[axis] - true_in_color[axis]).abs() < lateral_tolerance_m,
                "{point:?} vs {true_in_color:?}"
            );
        }
        let (u_c, v_c) = setup
            .color
            .project(point.point_in_camera_m)
            .expect("in front");
        assert!((u_c - point.u_px).abs() < 1e-9 && (v_c - point.v_px).abs() < 1e-9);
        let (u_true, v_true) = setup.color.project(true_in_color).expect("in front");
        let colour_px_per_depth_px = setup.color.fx_px / setup.depth.fx_px;
        assert!((u_true - point.u_px).abs() < colour_px_per_depth_px);
        assert!((v_true - point.v_px).abs() < colour_px_per_depth_px * 1.5);
    }

    #[test]
    fn zero_and_out_of_range_depth_are_counted_not_registered() {
        let setup = CameraSetup::tl460_simulated(RigidTransform::IDENTITY);
        let registration = DepthRegistration::new(
            setup.depth,
            setup.color,
            setup.color_from_depth,
            DepthRange::default(),
        );
        let n = (setup.depth.width_px * setup.depth.height_px) as usize;
        let mut data = vec![0_u16; n];
        data[0] = 100; // too close
        data[1] = 9_999; // too far
        let centre =
            (setup.depth.height_px / 2 * setup.depth.width_px + setup.depth.width_px / 2) as usize;
        data[centre] = 1500;
        let view = DepthView {
            width_px: setup.depth.width_px,
            height_px: setup.depth.height_px,
            data: &data,
        };
        let mut visited = Vec::new();
        let counts = registration
            .register(&view, |p| visited.push(*p))
            .expect("valid frame");
        assert_eq!(counts.zero as usize, n - 3);
        assert_eq!(counts.out_of_range, 2);
        assert_eq!(counts.registered, 1);
        assert_eq!(visited.len(), 1);
        assert!((visited[0].point_in_camera_m[2] - 1.5).abs() < 0.01);

        let short = DepthView {
            width_px: setup.depth.width_px,
            height_px: setup.depth.height_px,
            data: &data[1..],
        };
        assert!(registration.register(&short, |_| {}).is_err());
    }
}
