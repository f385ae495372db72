//! Laser triangulation ([alacs sec. 4.1]): from a pixel on the laser stripe to a 3D point
//! in the ALACS camera frame.
//!
//! - High-fidelity model, eq. 7-8: `z = L / (sin a - u_bar cos a - v_bar tan b)`,
//!   `x = z u_bar`, `y = z v_bar`, with `L = L0 - d`.
//! - Low-fidelity model, eq. 10: the same with `beta = 0`, so `v_bar` drops out.
//!
//! `(u_bar, v_bar)` are undistorted normalised coordinates, obtained from the pixel through the
//! camera intrinsics and distortion (eq. 3, [`CameraIntrinsics::normalize`]).

use harvest_hw::alacs::AlacsExtrinsics;
use harvest_ipc::camera_model::CameraIntrinsics;
use serde::{Deserialize, Serialize};

/// Smallest accepted denominator of eq. 7; below it the ray runs (nearly) parallel to the laser
/// plane or meets it behind the camera, and no depth is returned.
pub const MIN_DENOMINATOR: f64 = 1e-6;

/// Which triangulation model to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TriangulationModel {
    /// eq. 7-8 with `alpha`, `L` and `beta`.
    HighFidelity,
    /// eq. 10: `alpha` and `L` only (`beta` taken as 0).
    LowFidelity,
}

/// Depth `z` (m) of the stripe point seen along normalised ray `(u_bar, v_bar, 1)` by the
/// high-fidelity model (eq. 7); `None` when the ray does not meet the laser plane in front of
/// the camera.
pub fn high_fidelity_depth_m(
    alpha_rad: f64,
    baseline_m: f64,
    beta_rad: f64,
    u_bar: f64,
    v_bar: f64,
) -> Option<f64> {
    let denominator = alpha_rad.sin() - u_bar * alpha_rad.cos() - v_bar * beta_rad.tan();
    depth_from_denominator(baseline_m, denominator)
}

/// Depth `z` (m) by the low-fidelity model (eq. 10), which ignores `beta` and `v_bar`.
pub fn low_fidelity_depth_m(alpha_rad: f64, baseline_m: f64, u_bar: f64) -> Option<f64> {
    let denominator = alpha_rad.sin() - u_bar * alpha_rad.cos();
    depth_from_denominator(baseline_m, denominator)
}

fn depth_from_denominator(baseline_m: f64, denominator: f64) -> Option<f64> {
    let depth_m = baseline_m / denominator;
    (denominator >= MIN_DENOMINATOR && baseline_m > 0.0 && depth_m.is_finite()).then_some(depth_m)
}

/// Turns stripe pixels into 3D points with one camera and one set of extrinsics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserTriangulator {
    pub intrinsics: CameraIntrinsics,
    pub extrinsics: AlacsExtrinsics,
    pub model: TriangulationModel,
}

impl LaserTriangulator {
    /// A high-fidelity triangulator.
    pub fn new(intrinsics: CameraIntrinsics, extrinsics: AlacsExtrinsics) -> Self {
        Self {
            intrinsics,
            extrinsics,
            model: TriangulationModel::HighFidelity,
        }
    }

    /// The stripe point seen at normalised coordinates `(u_bar, v_bar)` with the slide at
    /// `slide_position_m` (eq. 7-8, or eq. 10 for the low-fidelity model), camera frame, m.
    pub fn point_from_normalized(
        &self,
        slide_position_m: f64,
        u_bar: f64,
        v_bar: f64,
    ) -> Option<[f64; 3]> {
        let baseline_m = self.extrinsics.baseline_m(slide_position_m);
        let depth_m = match self.model {
            TriangulationModel::HighFidelity => high_fidelity_depth_m(
                self.extrinsics.alpha_rad,
                baseline_m,
                self.extrinsics.beta_rad,
                u_bar,
                v_bar,
            ),
            TriangulationModel::LowFidelity => {
                low_fidelity_depth_m(self.extrinsics.alpha_rad, baseline_m, u_bar)
            }
        }?;
        Some([depth_m * u_bar, depth_m * v_bar, depth_m])
    }

    /// The stripe point seen at pixel `(u_px, v_px)`: eq. 3 (undistort, normalise) then eq. 7-8.
    pub fn point_from_pixel(
        &self,
        slide_position_m: f64,
        u_px: f64,
        v_px: f64,
    ) -> Option<[f64; 3]> {
        let (u_bar, v_bar) = self.intrinsics.normalize(u_px, v_px);
        self.point_from_normalized(slide_position_m, u_bar, v_bar)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::alacs::alacs_camera_intrinsics;

    #[test]
    fn high_fidelity_points_lie_on_the_hardware_laser_plane() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let triangulator = LaserTriangulator::new(alacs_camera_intrinsics(), extrinsics);
        for slide_position_m in [0.0, 0.05, 0.2] {
            let plane = extrinsics.laser_plane_in_camera(slide_position_m);
            for (u_px, v_px) in [(300.0, 100.0), (720.0, 540.0), (1100.0, 1000.0)] {
                let Some(point) = triangulator.point_from_pixel(slide_position_m, u_px, v_px)
                else {
                    continue;
                };
                assert!(plane.signed_distance_m(point).abs() < 1e-12, "{point:?}");
                let (u_back, v_back) = triangulator.intrinsics.project(point).expect("in front");
                assert!((u_back - u_px).abs() < 1e-6 && (v_back - v_px).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn low_fidelity_equals_high_fidelity_when_beta_is_zero_or_on_the_centre_row() {
        let alpha_rad = 19.07_f64.to_radians();
        let high = high_fidelity_depth_m(alpha_rad, 0.38, 0.0, -0.1, 0.25).expect("depth");
        let low = low_fidelity_depth_m(alpha_rad, 0.38, -0.1).expect("depth");
        assert!((high - low).abs() < 1e-15);
        let beta_rad = 0.69_f64.to_radians();
        let on_axis = high_fidelity_depth_m(alpha_rad, 0.38, beta_rad, -0.1, 0.0).expect("depth");
        assert!((on_axis - low).abs() < 1e-15);
        // Away from the centre row the ignored beta shifts the depth by millimetres.
        let off_axis = high_fidelity_depth_m(alpha_rad, 0.38, beta_rad, -0.1, 0.3).expect("depth");
        assert!((off_axis - low).abs() > 1e-3);
    }

    #[test]
    fn rays_parallel_to_or_behind_the_plane_have_no_depth() {
        let alpha_rad = 19.07_f64.to_radians();
        // u_bar = tan(alpha): the ray is parallel to the laser plane.
        assert!(low_fidelity_depth_m(alpha_rad, 0.38, alpha_rad.tan()).is_none());
        assert!(low_fidelity_depth_m(alpha_rad, 0.38, 1.0).is_none());
        assert!(low_fidelity_depth_m(alpha_rad, 0.38, f64::NAN).is_none());
    }
}
