//! One calibration sample `s_i = [u_bar, v_bar, z]` ([alacs sec. 4.2]) and the checks a
//! sample set must pass before any fit.

use serde::{Deserialize, Serialize};

use super::error::CalibrationError;

/// A laser point seen on the calibration board: its undistorted normalised image coordinates
/// (eq. 3) and its depth from the board pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationSample {
    pub u_bar: f64,
    pub v_bar: f64,
    /// Depth `z_c` of the point in the camera frame, m.
    pub z_m: f64,
}

/// Fewest samples any method accepts: Algorithm 1 draws 4-sample hypotheses.
pub const MIN_SAMPLES: usize = 4;

/// Smallest depth range the samples must span, m. With every sample at one depth the points lie
/// on one image line and `alpha`, `L0`, `beta` cannot be separated.
pub const MIN_DEPTH_SPREAD_M: f64 = 0.01;

/// Checks count, finiteness, positive depth and depth spread; the error names the first
/// offending sample (0-based index) and field.
pub fn validate_samples(samples: &[CalibrationSample]) -> Result<(), CalibrationError> {
    if samples.len() < MIN_SAMPLES {
        return Err(CalibrationError::TooFewSamples {
            got: samples.len(),
            needed: MIN_SAMPLES,
        });
    }
    for (index, sample) in samples.iter().enumerate() {
        for (field, value) in [
            ("u_bar", sample.u_bar),
            ("v_bar", sample.v_bar),
            ("z_m", sample.z_m),
        ] {
            if !value.is_finite() {
                return Err(CalibrationError::NonFiniteSample {
                    index,
                    field,
                    value,
                });
            }
        }
        if sample.z_m <= 0.0 {
            return Err(CalibrationError::NonPositiveDepth {
                index,
                z_m: sample.z_m,
            });
        }
    }
    let (min_m, max_m) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.z_m), hi.max(s.z_m))
        });
    if max_m - min_m < MIN_DEPTH_SPREAD_M {
        return Err(CalibrationError::SingleDepth {
            depth_m: 0.5 * (min_m + max_m),
            spread_m: max_m - min_m,
            needed_m: MIN_DEPTH_SPREAD_M,
        });
    }
    Ok(())
}
