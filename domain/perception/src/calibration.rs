//! The perception process's calibration file: where the camera sits on the robot.

use harvest_ipc::camera_model::RigidTransform;
use serde::Deserialize;
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    pub camera: CameraCalibration,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraCalibration {
    /// Pose of the colour sensor in the robot frame.
    pub robot_from_camera: RigidTransform,
}

/// A calibration file that cannot be used (file, line and key named).
pub type CalibrationError = harvest_ipc::config_file::ConfigFileError;

/// What the file holds, in errors.
const WHAT: &str = "calibration file";

impl Calibration {
    pub fn from_path(path: &Path) -> Result<Self, CalibrationError> {
        harvest_ipc::config_file::read_toml(path, WHAT)
    }

    pub fn parse(text: &str, origin: &str) -> Result<Self, CalibrationError> {
        harvest_ipc::config_file::parse_toml(text, origin, WHAT)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The simulated robot's calibration file (what its launch profiles pass).
    const SIM_CALIBRATION: &str = include_str!("../../../sim/camera_calibration.toml");

    #[test]
    fn sim_calibration_parses_and_unknown_keys_are_named() {
        let calibration =
            Calibration::parse(SIM_CALIBRATION, "sim/camera_calibration.toml").expect("parses");
        assert!((calibration.camera.robot_from_camera.translation_m[2] - 0.9).abs() < 1e-12);
        let bad = SIM_CALIBRATION.replace("translation_m", "translation_mm");
        let message = Calibration::parse(&bad, "bad.toml")
            .expect_err("unknown key")
            .to_string();
        assert!(
            message.contains("bad.toml") && message.contains("translation_mm"),
            "{message}"
        );
    }
}
