//! Extrinsic calibration of the ALACS unit ([alacs sec. 4.2 and 5.1]): samples
//! `[u_bar, v_bar, z]`, the two depth models, least squares (problem 9), RANSAC (Algorithm 1),
//! the four compared methods, and the calibration file.

pub mod csv;
pub mod error;
pub mod file;
pub mod fit;
pub mod least_squares;
pub mod methods;
pub mod model;
pub mod sample;

pub use csv::{SampleFileError, parse_samples_csv, read_samples_csv, write_samples_csv};
pub use error::CalibrationError;
pub use file::{
    CalibrationFileError, ExtrinsicsRecord, FitRecord, LaserCalibrationFile, read_calibration_file,
    read_extrinsics, write_calibration_file,
};
pub use fit::{FitOutcome, RansacOptions, fit_all, fit_ransac};
pub use least_squares::{LmOptions, LmSolution, levenberg_marquardt};
pub use methods::{
    Calibration, CalibrationMethod, CalibrationOptions, CalibrationReport, EvaluationSet,
    MethodResult, PaperRow, calibrate, compare_methods, mean_abs_depth_error_m,
};
pub use model::{DepthModel, HighFidelity, LowFidelity};
pub use sample::{CalibrationSample, MIN_DEPTH_SPREAD_M, MIN_SAMPLES, validate_samples};
