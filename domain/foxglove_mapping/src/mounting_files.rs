//! Where the sensors sit, read from the files the stack already uses: perception's camera
//! calibration (`robot_from_camera`) and the LiDAR extrinsic (`camera_from_lidar`). The mapping
//! itself takes plain transforms ([`crate::Mounting`]); this module only reads them.

use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::config_file::ConfigFileError;
use harvest_lidar::extrinsic_file::ExtrinsicFile;
use harvest_perception::calibration::Calibration;
use std::path::Path;

/// Why a mounting file could not be used (file, line and key named).
#[derive(Debug, thiserror::Error)]
pub enum MountingError {
    #[error(transparent)]
    File(#[from] ConfigFileError),
    /// The transform in the file is not a rigid motion.
    #[error("{origin}: {key} is not a rigid transform (orthonormal rotation, determinant +1)")]
    NotRigid { origin: String, key: &'static str },
}

fn checked(
    transform: RigidTransform,
    origin: &str,
    key: &'static str,
) -> Result<RigidTransform, MountingError> {
    if transform.is_rigid() {
        Ok(transform)
    } else {
        Err(MountingError::NotRigid {
            origin: origin.to_owned(),
            key,
        })
    }
}

/// `robot_from_camera` from a camera calibration file.
pub fn robot_from_camera_file(path: &Path) -> Result<RigidTransform, MountingError> {
    let calibration = Calibration::from_path(path)?;
    checked(
        calibration.camera.robot_from_camera,
        &path.display().to_string(),
        "camera.robot_from_camera",
    )
}

/// `robot_from_camera` from a calibration file's text (a recording's `harvest.calibration`
/// record); `origin` names where the text came from in errors.
pub fn robot_from_camera_text(text: &str, origin: &str) -> Result<RigidTransform, MountingError> {
    let calibration = Calibration::parse(text, origin)?;
    checked(
        calibration.camera.robot_from_camera,
        origin,
        "camera.robot_from_camera",
    )
}

/// `camera_from_lidar` from a LiDAR extrinsic file.
pub fn camera_from_lidar_file(path: &Path) -> Result<RigidTransform, MountingError> {
    let file = ExtrinsicFile::read(path)?;
    checked(
        file.camera_from_lidar,
        &path.display().to_string(),
        "camera_from_lidar",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const SIM_CALIBRATION: &str = include_str!("../../../sim/camera_calibration.toml");

    #[test]
    fn reads_the_sim_calibration_and_names_bad_ones() {
        let transform =
            robot_from_camera_text(SIM_CALIBRATION, "sim/camera_calibration.toml").expect("ok");
        assert_eq!(transform.translation_m, [0.0, -0.025, 0.9]);
        let skewed = SIM_CALIBRATION.replace("[-1.0, 0.0, 0.0]", "[-2.0, 0.0, 0.0]");
        let error = robot_from_camera_text(&skewed, "bad.toml").expect_err("not rigid");
        assert!(error.to_string().contains("bad.toml"), "{error}");
        let lidar = camera_from_lidar_file(Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../sim/lidar_extrinsic.toml"
        )))
        .expect("sim extrinsic");
        assert!(lidar.is_rigid());
    }
}
