//! Frames of the LiDAR and its nominal (CAD) mounting on the colour camera.
//!
//! LiDAR frame (Livox): x forward along the boresight, y left, z up. Camera optical frame (the
//! stack's convention, `harvest_ipc::camera_model`): x right, y down, z forward.

use harvest_ipc::camera_model::RigidTransform;

/// Rotation from the LiDAR frame to an optical frame at the same origin looking along the
/// boresight: optical x = -lidar y, optical y = -lidar z, optical z = lidar x.
pub const OPTICAL_FROM_LIDAR: RigidTransform = RigidTransform {
    rotation: [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]],
    translation_m: [0.0; 3],
};

/// The extrinsic `camera_from_lidar` (T_L^C in [fusion eq. 2]) as designed: the LiDAR sits 80 mm
/// above the colour camera's optical centre (camera -y), boresight parallel to the optical axis.
/// This is the initial guess of the calibration; the built unit differs by its assembly error.
pub const CAD_CAMERA_FROM_LIDAR: RigidTransform = RigidTransform {
    rotation: OPTICAL_FROM_LIDAR.rotation,
    translation_m: [0.0, -0.08, 0.0],
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boresight_maps_to_the_optical_axis() {
        let forward = OPTICAL_FROM_LIDAR.rotate([1.0, 0.0, 0.0]);
        assert_eq!(forward, [0.0, 0.0, 1.0]);
        let up = OPTICAL_FROM_LIDAR.rotate([0.0, 0.0, 1.0]);
        assert_eq!(up, [0.0, -1.0, 0.0]);
        let left = OPTICAL_FROM_LIDAR.rotate([0.0, 1.0, 0.0]);
        assert_eq!(left, [-1.0, 0.0, 0.0]);
    }
}
