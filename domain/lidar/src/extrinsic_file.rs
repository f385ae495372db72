//! The LiDAR-camera extrinsic file `harvest calibrate lidar-camera --output` writes and the
//! perception process reads (`--lidar-extrinsic`).

use harvest_ipc::camera_model::RigidTransform;

/// The extrinsic file written by `harvest calibrate lidar-camera --output`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtrinsicFile {
    pub camera_from_lidar: RigidTransform,
    pub average_error_px: f64,
    pub normalized_error_px: f64,
}

/// Why an extrinsic file cannot be used (file, line and key named).
pub type ReadExtrinsicError = harvest_ipc::config_file::ConfigFileError;

impl ExtrinsicFile {
    /// Reads a file written by `harvest calibrate lidar-camera --output`.
    pub fn read(path: &std::path::Path) -> Result<Self, ReadExtrinsicError> {
        harvest_ipc::config_file::read_toml(path, "LiDAR extrinsic")
    }
}
