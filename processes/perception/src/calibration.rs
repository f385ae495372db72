//! The perception process's calibration file: where the camera sits on the robot.

use harvest_ipc::camera_model::RigidTransform;
use serde::Deserialize;
use std::path::Path;

/// The calibration used when no file is given (matches the simulated robot's default camera).
pub const DEFAULT_CALIBRATION: &str = include_str!("../calibration/default.toml");

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

    pub fn default_calibration() -> Result<Self, CalibrationError> {
        Self::parse(DEFAULT_CALIBRATION, "<embedded calibration/default.toml>")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_parses_and_unknown_keys_are_named() {
        let calibration = Calibration::default_calibration().expect("default calibration");
        assert!((calibration.camera.robot_from_camera.translation_m[2] - 0.9).abs() < 1e-12);
        let bad = DEFAULT_CALIBRATION.replace("translation_m", "translation_mm");
        let message = Calibration::parse(&bad, "bad.toml")
            .expect_err("unknown key")
            .to_string();
        assert!(
            message.contains("bad.toml") && message.contains("translation_mm"),
            "{message}"
        );
    }
}
