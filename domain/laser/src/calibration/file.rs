//! The ALACS calibration file (TOML): the chosen extrinsics in readable units plus a summary of
//! the fit that produced them.
//!
//! ```toml
//! [extrinsics]
//! alpha_deg = 19.07
//! l0_mm = 381.98
//! beta_deg = 0.69
//!
//! [fit]
//! method = "high_fidelity_ransac"
//! samples = 30
//! used_samples = 27
//! epsilon_mm = 2.0
//! mean_abs_error_mm = 0.39
//! ```

use std::path::{Path, PathBuf};

use harvest_hw::alacs::AlacsExtrinsics;
use serde::{Deserialize, Serialize};

use super::methods::CalibrationMethod;

/// The whole file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaserCalibrationFile {
    pub extrinsics: ExtrinsicsRecord,
    pub fit: FitRecord,
}

/// eq. 7's parameters in degrees and millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtrinsicsRecord {
    pub alpha_deg: f64,
    pub l0_mm: f64,
    pub beta_deg: f64,
}

/// How the parameters were obtained.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitRecord {
    pub method: CalibrationMethod,
    pub samples: usize,
    pub used_samples: usize,
    pub epsilon_mm: f64,
    pub mean_abs_error_mm: f64,
}

impl LaserCalibrationFile {
    /// The extrinsics in SI units, checked (finite, `L0` longer than the stroke).
    pub fn alacs_extrinsics(&self) -> Option<AlacsExtrinsics> {
        let extrinsics = AlacsExtrinsics {
            alpha_rad: self.extrinsics.alpha_deg.to_radians(),
            l0_m: self.extrinsics.l0_mm * 1e-3,
            beta_rad: self.extrinsics.beta_deg.to_radians(),
        };
        extrinsics.is_valid().then_some(extrinsics)
    }
}

/// Why the calibration file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax, a missing or unknown key, or a wrongly typed value.
    #[error("{path}:{line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// Values that are not usable extrinsics.
    #[error("{path}: [extrinsics] {values:?} are not usable ALACS extrinsics")]
    InvalidExtrinsics {
        path: PathBuf,
        values: ExtrinsicsRecord,
    },
    #[error("could not encode the calibration file: {0}")]
    Encode(#[from] toml::ser::Error),
}

/// Writes `file` to `path` atomically (a sibling temporary file renamed over `path`), so a
/// failed write never leaves a half-written calibration.
pub fn write_calibration_file(
    path: &Path,
    file: &LaserCalibrationFile,
) -> Result<(), CalibrationFileError> {
    if file.alacs_extrinsics().is_none() {
        return Err(CalibrationFileError::InvalidExtrinsics {
            path: path.to_path_buf(),
            values: file.extrinsics,
        });
    }
    let text = format!(
        "# ALACS laser-camera extrinsics ([alacs eq. 7]), written by `harvest calibrate laser`.\n{}",
        toml::to_string(file)?
    );
    let mut temporary = path.as_os_str().to_owned();
    temporary.push(".tmp");
    let temporary = PathBuf::from(temporary);
    let io_error = |source| CalibrationFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    std::fs::write(&temporary, text).map_err(io_error)?;
    std::fs::rename(&temporary, path).map_err(|source| {
        let _ = std::fs::remove_file(&temporary);
        io_error(source)
    })
}

/// Reads and checks a calibration file.
pub fn read_calibration_file(path: &Path) -> Result<LaserCalibrationFile, CalibrationFileError> {
    let text = std::fs::read_to_string(path).map_err(|source| CalibrationFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file: LaserCalibrationFile =
        toml::from_str(&text).map_err(|error| CalibrationFileError::Parse {
            path: path.to_path_buf(),
            line: error.span().map_or(0, |span| {
                text[..span.start.min(text.len())].matches('\n').count() + 1
            }),
            message: error.message().to_string(),
        })?;
    if file.alacs_extrinsics().is_none() {
        return Err(CalibrationFileError::InvalidExtrinsics {
            path: path.to_path_buf(),
            values: file.extrinsics,
        });
    }
    Ok(file)
}

/// The extrinsics of the calibration file at `path` (what the laser scans with and what its
/// reach is computed from, [`crate::reach::LaserReach`]).
pub fn read_extrinsics(path: &Path) -> Result<AlacsExtrinsics, CalibrationFileError> {
    let file = read_calibration_file(path)?;
    file.alacs_extrinsics()
        .ok_or_else(|| CalibrationFileError::InvalidExtrinsics {
            path: path.to_path_buf(),
            values: file.extrinsics,
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("harvest-laser-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        dir
    }

    fn example() -> LaserCalibrationFile {
        LaserCalibrationFile {
            extrinsics: ExtrinsicsRecord {
                alpha_deg: 19.07,
                l0_mm: 381.98,
                beta_deg: 0.69,
            },
            fit: FitRecord {
                method: CalibrationMethod::HighFidelityRansac,
                samples: 30,
                used_samples: 27,
                epsilon_mm: 2.0,
                mean_abs_error_mm: 0.39,
            },
        }
    }

    #[test]
    fn round_trip() {
        let dir = temp_dir("toml-round-trip");
        let path = dir.join("alacs.toml");
        write_calibration_file(&path, &example()).expect("write");
        let back = read_calibration_file(&path).expect("read");
        assert_eq!(back, example());
        let extrinsics = back.alacs_extrinsics().expect("valid");
        assert!((extrinsics.l0_m - 0.38198).abs() < 1e-12);
        assert!(!dir.join("alacs.toml.tmp").exists());
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn unknown_keys_and_bad_values_are_refused_with_the_line() {
        let dir = temp_dir("toml-bad");
        let path = dir.join("alacs.toml");
        let text = "[extrinsics]\nalpha_deg = 19.0\nl0_mm = 382.0\nbeta_deg = 0.7\ngamma = 1\n\n[fit]\nmethod = \"high_fidelity_ransac\"\nsamples = 30\nused_samples = 27\nepsilon_mm = 2.0\nmean_abs_error_mm = 0.4\n";
        std::fs::write(&path, text).expect("write");
        let error = read_calibration_file(&path).expect_err("unknown key");
        let message = error.to_string();
        assert!(
            message.contains("alacs.toml:5:") && message.contains("gamma"),
            "{message}"
        );

        std::fs::write(
            &path,
            text.replace("gamma = 1\n", "").replace("382.0", "100.0"),
        )
        .expect("write");
        assert!(matches!(
            read_calibration_file(&path),
            Err(CalibrationFileError::InvalidExtrinsics { .. })
        ));
        let mut bad = example();
        bad.extrinsics.alpha_deg = f64::NAN;
        let other = dir.join("nan.toml");
        assert!(write_calibration_file(&other, &bad).is_err());
        assert!(!other.exists());
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}
