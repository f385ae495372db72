//! Depth noise model of the ToF camera.
//!
//! The Percipio TL460-S1-E1 datasheet ([dual-arm sec. 2.1]) specifies a depth accuracy of
//! +/-(4 mm + 0.25 % of depth) over a 0.3-9.5 m range. This crate uses that band as a one-sigma
//! noise scale: it sizes DBSCAN neighbourhoods and the sphere-fit inlier tolerances.

use serde::{Deserialize, Serialize};

/// Depth noise scale `sigma(z) = base_m + fraction_of_depth * z`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DepthNoiseModel {
    /// Constant part of the depth accuracy, metres (4 mm for the TL460).
    pub base_m: f64,
    /// Depth-proportional part of the accuracy, dimensionless (0.25 % for the TL460).
    pub fraction_of_depth: f64,
}

impl Default for DepthNoiseModel {
    fn default() -> Self {
        Self::TL460
    }
}

impl DepthNoiseModel {
    /// The TL460-S1-E1 datasheet values.
    pub const TL460: Self = Self {
        base_m: 0.004,
        fraction_of_depth: 0.0025,
    };

    /// Noise scale (metres) of a depth sample at `depth_m`.
    pub fn sigma_m(&self, depth_m: f64) -> f64 {
        self.base_m + self.fraction_of_depth * depth_m.abs()
    }

    /// True when both coefficients are finite and non-negative and the scale is positive.
    pub fn is_valid(&self) -> bool {
        self.base_m.is_finite()
            && self.fraction_of_depth.is_finite()
            && self.base_m >= 0.0
            && self.fraction_of_depth >= 0.0
            && self.base_m + self.fraction_of_depth > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tl460_accuracy_at_one_and_four_metres() {
        let noise = DepthNoiseModel::default();
        assert!((noise.sigma_m(1.0) - 0.0065).abs() < 1e-12);
        assert!((noise.sigma_m(4.0) - 0.014).abs() < 1e-12);
        assert!(noise.is_valid());
        let bad = DepthNoiseModel {
            base_m: f64::NAN,
            fraction_of_depth: 0.0,
        };
        assert!(!bad.is_valid());
    }
}
