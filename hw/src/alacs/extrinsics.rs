//! Laser-camera extrinsics of the ALACS unit and the laser plane they imply ([alacs
//! sec. 4.1, eq. 4-8]).
//!
//! Frames ([alacs Fig. 4]): the camera frame `F_c` follows the stack convention (x right, y down,
//! z forward, metres). The laser frame `F_l` has its origin on the laser emitter, `z_l` along the
//! centre of the fan and the fan spanning the `(y_l, z_l)` plane when `beta = 0`. The slide moves
//! the emitter along `x_l`; moving it by `d` towards the camera shortens the laser-camera distance
//! to `L = L0 - d` ([alacs sec. 5.2]).

use harvest_ipc::camera_model::RigidTransform;
use serde::{Deserialize, Serialize};

use super::error::AlacsError;

/// Full stroke of the linear slide: the slide position `d` lives in `[0, SLIDE_STROKE_M]`
/// (20 cm, [alacs sec. 3]).
pub const SLIDE_STROKE_M: f64 = 0.20;

/// Slack allowed on the stroke ends when validating a requested position (floating-point
/// round-off of `0.19 + 0.01`, not a mechanical tolerance).
const STROKE_SLACK_M: f64 = 1e-9;

/// Checks that `slide_position_m` is finite and inside the stroke `[0, SLIDE_STROKE_M]`.
///
/// Every [`super::AlacsUnit`] implementation and the renderer use this one check, so "outside
/// the stroke" means the same thing everywhere.
pub fn check_slide_position(slide_position_m: f64) -> Result<(), AlacsError> {
    if slide_position_m.is_finite()
        && (-STROKE_SLACK_M..=SLIDE_STROKE_M + STROKE_SLACK_M).contains(&slide_position_m)
    {
        Ok(())
    } else {
        Err(AlacsError::SlideOutOfStroke {
            requested_m: slide_position_m,
            stroke_m: SLIDE_STROKE_M,
        })
    }
}

/// The three extrinsic parameters of the high-fidelity model ([alacs eq. 4-7]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AlacsExtrinsics {
    /// `alpha`: rotation about `y_l` between the laser frame and the camera frame ([alacs eq. 4]), rad.
    pub alpha_rad: f64,
    /// `L0`: laser-camera distance along `x_l` with the slide at its home position `d = 0`, m.
    pub l0_m: f64,
    /// `beta`: angle between the laser plane and the `(y_l, z_l)` plane ([alacs eq. 5]), rad.
    pub beta_rad: f64,
}

impl AlacsExtrinsics {
    /// The values the ALACS paper calibrated with its own method ([alacs Table 1], method 4): alpha 19.07 deg,
    /// L0 381.98 mm, beta 0.69 deg. Used as the simulated unit's ground truth.
    pub fn paper_table1() -> Self {
        Self {
            alpha_rad: 19.07_f64.to_radians(),
            l0_m: 0.38198,
            beta_rad: 0.69_f64.to_radians(),
        }
    }

    /// True when all three parameters are finite and `L0` is longer than the stroke (so the
    /// baseline `L = L0 - d` stays positive over the whole stroke).
    pub fn is_valid(&self) -> bool {
        self.alpha_rad.is_finite()
            && self.l0_m.is_finite()
            && self.beta_rad.is_finite()
            && self.l0_m > SLIDE_STROKE_M
            && self.alpha_rad.abs() < std::f64::consts::FRAC_PI_2
            && self.beta_rad.abs() < std::f64::consts::FRAC_PI_2
    }

    /// Laser-camera distance `L = L0 - d` for slide position `d` ([alacs sec. 5.2]), m.
    pub fn baseline_m(&self, slide_position_m: f64) -> f64 {
        self.l0_m - slide_position_m
    }

    /// `camera_from_laser` at slide position `d`: the rotation about `y` by `alpha` and the
    /// translation `(-L cos alpha, 0, L sin alpha)` of [alacs eq. 4].
    pub fn camera_from_laser(&self, slide_position_m: f64) -> RigidTransform {
        let (sin_a, cos_a) = self.alpha_rad.sin_cos();
        let baseline_m = self.baseline_m(slide_position_m);
        RigidTransform {
            rotation: [[cos_a, 0.0, sin_a], [0.0, 1.0, 0.0], [-sin_a, 0.0, cos_a]],
            translation_m: [-baseline_m * cos_a, 0.0, baseline_m * sin_a],
        }
    }

    /// The laser plane in the camera frame at slide position `d`.
    ///
    /// The plane `x_l + y_l tan(beta) = 0` ([alacs eq. 5]) mapped through [alacs eq. 4] is
    /// `x cos(alpha) + y tan(beta) - z sin(alpha) + L = 0`, which gives [alacs eq. 7] once `x = z u_bar`
    /// and `y = z v_bar` are substituted.
    pub fn laser_plane_in_camera(&self, slide_position_m: f64) -> LaserPlane {
        let (sin_a, cos_a) = self.alpha_rad.sin_cos();
        LaserPlane {
            normal: [cos_a, self.beta_rad.tan(), -sin_a],
            offset_m: self.baseline_m(slide_position_m),
        }
    }

    /// Direction of the centre of the laser fan (`z_l`) in the camera frame.
    pub fn laser_axis_in_camera(&self) -> [f64; 3] {
        let (sin_a, cos_a) = self.alpha_rad.sin_cos();
        [sin_a, 0.0, cos_a]
    }
}

/// A plane `normal . p + offset_m = 0` in the camera frame, with `normal` *not* normalised:
/// for the laser plane `normal = (cos alpha, tan beta, -sin alpha)` and `offset_m = L`, so that
/// the depth along a normalised ray `(u_bar, v_bar, 1)` is `-offset / (normal . ray)` [alacs eq. 7].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaserPlane {
    /// The plane's normal (not normalised), camera frame.
    pub normal: [f64; 3],
    /// The plane's offset `L`, metres.
    pub offset_m: f64,
}

impl LaserPlane {
    /// Unit normal, pointing to the side the slide moves the plane towards as `d` grows
    /// (image right for the geometry of [alacs Fig. 4]).
    pub fn unit_normal(&self) -> [f64; 3] {
        let norm = dot(self.normal, self.normal).sqrt();
        [
            self.normal[0] / norm,
            self.normal[1] / norm,
            self.normal[2] / norm,
        ]
    }

    /// Signed distance (m) from `point_in_camera_m` to the plane, positive on the side of
    /// [`Self::unit_normal`].
    pub fn signed_distance_m(&self, point_in_camera_m: [f64; 3]) -> f64 {
        (dot(self.normal, point_in_camera_m) + self.offset_m) / dot(self.normal, self.normal).sqrt()
    }

    /// Parameter `t > 0` at which the ray `origin + t * direction` meets the plane, if it does.
    pub fn intersect_ray(&self, origin: [f64; 3], direction: [f64; 3]) -> Option<f64> {
        let denominator = dot(self.normal, direction);
        if denominator.abs() < 1e-12 {
            return None;
        }
        let t = -(dot(self.normal, origin) + self.offset_m) / denominator;
        (t > 0.0 && t.is_finite()).then_some(t)
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laser_frame_points_map_onto_the_camera_plane() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        for slide_position_m in [0.0, 0.07, 0.2] {
            let camera_from_laser = extrinsics.camera_from_laser(slide_position_m);
            let plane = extrinsics.laser_plane_in_camera(slide_position_m);
            for (y_l, z_l) in [(0.0, 0.5), (-0.3, 0.9), (0.2, 1.3)] {
                // [alacs eq. 5]: x_l = -y_l tan(beta).
                let point_in_laser = [-y_l * extrinsics.beta_rad.tan(), y_l, z_l];
                let point_in_camera = camera_from_laser.apply(point_in_laser);
                assert!(plane.signed_distance_m(point_in_camera).abs() < 1e-12);
                // [alacs eq. 7] gives back the same depth from the normalised coordinates.
                let u_bar = point_in_camera[0] / point_in_camera[2];
                let v_bar = point_in_camera[1] / point_in_camera[2];
                let (sin_a, cos_a) = extrinsics.alpha_rad.sin_cos();
                let depth_m = extrinsics.baseline_m(slide_position_m)
                    / (sin_a - u_bar * cos_a - v_bar * extrinsics.beta_rad.tan());
                assert!((depth_m - point_in_camera[2]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn moving_the_slide_shifts_the_plane_right_by_the_slide_travel() {
        let extrinsics = AlacsExtrinsics::paper_table1();
        let plane_home = extrinsics.laser_plane_in_camera(0.0);
        let plane_moved = extrinsics.laser_plane_in_camera(0.01);
        let point_on_home = [
            (0.8 * extrinsics.alpha_rad.sin() - extrinsics.l0_m) / extrinsics.alpha_rad.cos(),
            0.0,
            0.8,
        ];
        assert!(plane_home.signed_distance_m(point_on_home).abs() < 1e-12);
        // The moved plane is 1 cm further along +normal (towards image right).
        let distance_m = plane_moved.signed_distance_m(point_on_home);
        let expected_m = -0.01 / (1.0 + extrinsics.beta_rad.tan().powi(2)).sqrt();
        assert!((distance_m - expected_m).abs() < 1e-12, "{distance_m}");
        assert!(plane_home.unit_normal()[0] > 0.9);
    }

    #[test]
    fn slide_positions_outside_the_stroke_are_refused() {
        assert!(check_slide_position(0.0).is_ok());
        assert!(check_slide_position(0.2).is_ok());
        assert!(check_slide_position(0.19 + 0.01).is_ok());
        for bad in [-0.001, 0.2001, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                check_slide_position(bad),
                Err(AlacsError::SlideOutOfStroke { .. })
            ));
        }
    }
}
