//! The default ALACS camera.

use harvest_ipc::camera_model::CameraIntrinsics;

/// Intrinsics of the ALACS RGB camera as simulated: a FLIR 1440x1080 colour camera with
/// 3.45 um pixels behind a 6 mm lens (fx = fy = 6 mm / 3.45 um = 1739 px, about 45 deg
/// horizontal field of view) and mild barrel distortion.
///
/// The field of view is what the unit's geometry ([alacs Fig. 4]) needs: with `alpha` about 19 deg and
/// `L0` about 0.38 m the laser line sits at `u_bar` = -0.33 for a target at 0.6 m with the slide
/// home, and at `u_bar` = +0.19 for a target at 1.2 m with the slide at the far end.
pub fn alacs_camera_intrinsics() -> CameraIntrinsics {
    let focal_px = 6.0e-3 / 3.45e-6;
    CameraIntrinsics {
        width_px: 1440,
        height_px: 1080,
        fx_px: focal_px,
        fy_px: focal_px,
        cx_px: 719.5,
        cy_px: 539.5,
        distortion: [-0.08, 0.05, 0.0, 0.0, 0.0],
    }
}
