//! Why a calibration could not produce parameters.

/// Failures of the calibration methods ([alacs sec. 4.2 and 5.1]).
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum CalibrationError {
    /// Fewer samples than one 4-sample hypothesis needs.
    #[error("{got} calibration samples given, at least {needed} needed")]
    TooFewSamples { got: usize, needed: usize },
    /// A sample holds NaN or infinity.
    #[error("calibration sample {index}: {field} = {value} is not finite")]
    NonFiniteSample {
        index: usize,
        field: &'static str,
        value: f64,
    },
    /// A sample's depth is zero or negative.
    #[error("calibration sample {index}: z_m = {z_m} is not a depth in front of the camera")]
    NonPositiveDepth { index: usize, z_m: f64 },
    /// All samples lie at (nearly) one depth: the board was never moved.
    #[error(
        "all calibration samples lie at one depth ({depth_m:.4} m, spread {spread_m:.4} m < {needed_m} m): move the board between images"
    )]
    SingleDepth {
        depth_m: f64,
        spread_m: f64,
        needed_m: f64,
    },
    /// The samples do not determine the parameters (collinear in the image, rank deficient).
    #[error("calibration is degenerate: {detail}")]
    Degenerate { detail: String },
    /// No hypothesis gathered enough inliers.
    #[error(
        "RANSAC found at most {best_inliers} inliers within {epsilon_m} m, {needed} needed: raise epsilon or check the data"
    )]
    NoConsensus {
        best_inliers: usize,
        needed: usize,
        epsilon_m: f64,
    },
    /// An option is out of range.
    #[error("calibration option {name} = {value} is invalid")]
    InvalidOption { name: &'static str, value: f64 },
}
