//! The calibrated camera rig the perception pipeline works with.

use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use thiserror::Error;

/// Intrinsics of both ToF-camera sensors and the two extrinsic transforms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSetup {
    /// Colour camera (1920x1080 on the TL460); detections and the "camera frame" refer to it.
    pub color: CameraIntrinsics,
    /// Depth camera (640x480 on the TL460).
    pub depth: CameraIntrinsics,
    /// Depth-to-colour registration: `point_in_color = color_from_depth.apply(point_in_depth)`.
    pub color_from_depth: RigidTransform,
    /// Pose of the colour camera in the robot frame.
    pub robot_from_camera: RigidTransform,
}

/// A camera rig parameter that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CameraSetupError {
    /// Intrinsics with zero or absurd size (over 64 Mpx), a non-positive or non-finite focal
    /// length, or a non-finite principal point or distortion coefficient.
    #[error(
        "{camera} camera intrinsics are invalid: {width_px}x{height_px} px, fx={fx_px}, fy={fy_px}, cx={cx_px}, cy={cy_px}, distortion={distortion:?}"
    )]
    InvalidIntrinsics {
        camera: &'static str,
        width_px: u32,
        height_px: u32,
        fx_px: f64,
        fy_px: f64,
        cx_px: f64,
        cy_px: f64,
        distortion: [f64; 5],
    },
    /// A transform with non-finite entries or a rotation that is not proper (orthonormal to
    /// 1e-6, determinant +1).
    #[error("transform {name} is not a finite rigid transform: {transform:?}")]
    InvalidTransform {
        name: &'static str,
        transform: RigidTransform,
    },
}

impl CameraSetup {
    /// Checks every intrinsic and extrinsic parameter (finite, positive focal lengths, orthonormal
    /// rotations).
    pub fn validate(&self) -> Result<(), CameraSetupError> {
        check_intrinsics("colour", &self.color)?;
        check_intrinsics("depth", &self.depth)?;
        check_transform("color_from_depth", &self.color_from_depth)?;
        check_transform("robot_from_camera", &self.robot_from_camera)?;
        Ok(())
    }

    /// The simulated TL460 rig: default intrinsics, the depth sensor 35 mm left of the colour
    /// sensor with a slight misalignment, and the given camera pose.
    pub fn tl460_simulated(robot_from_camera: RigidTransform) -> Self {
        Self {
            color: CameraIntrinsics::tl460_rgb(),
            depth: CameraIntrinsics::tl460_depth(),
            color_from_depth: RigidTransform::from_rpy_translation(
                0.002,
                -0.003,
                0.001,
                [-0.035, 0.002, 0.001],
            ),
            robot_from_camera,
        }
    }
}

/// Largest accepted image (per-pixel tables are allocated from the intrinsics): 64 Mpx.
const MAX_IMAGE_PIXELS: u64 = 1 << 26;

fn check_intrinsics(camera: &'static str, k: &CameraIntrinsics) -> Result<(), CameraSetupError> {
    let valid =
        k.problem().is_none() && u64::from(k.width_px) * u64::from(k.height_px) <= MAX_IMAGE_PIXELS;
    if valid {
        Ok(())
    } else {
        Err(CameraSetupError::InvalidIntrinsics {
            camera,
            width_px: k.width_px,
            height_px: k.height_px,
            fx_px: k.fx_px,
            fy_px: k.fy_px,
            cx_px: k.cx_px,
            cy_px: k.cy_px,
            distortion: k.distortion,
        })
    }
}

fn check_transform(name: &'static str, t: &RigidTransform) -> Result<(), CameraSetupError> {
    if t.is_rigid() {
        Ok(())
    } else {
        Err(CameraSetupError::InvalidTransform {
            name,
            transform: *t,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulated_rig_is_valid_and_nan_is_rejected() {
        let setup = CameraSetup::tl460_simulated(RigidTransform::IDENTITY);
        assert_eq!(setup.validate(), Ok(()));

        let mut nan_intrinsics = setup;
        nan_intrinsics.depth.fx_px = f64::NAN;
        assert!(matches!(
            nan_intrinsics.validate(),
            Err(CameraSetupError::InvalidIntrinsics {
                camera: "depth",
                ..
            })
        ));

        let mut huge = setup;
        huge.color.width_px = 100_000;
        huge.color.height_px = 100_000;
        assert!(matches!(
            huge.validate(),
            Err(CameraSetupError::InvalidIntrinsics {
                camera: "colour",
                ..
            })
        ));

        let mut skewed = setup;
        skewed.robot_from_camera.rotation[0][1] = 0.3;
        assert!(matches!(
            skewed.validate(),
            Err(CameraSetupError::InvalidTransform {
                name: "robot_from_camera",
                ..
            })
        ));
    }
}
