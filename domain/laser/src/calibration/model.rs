//! The two depth models calibrated in [alacs sec. 5.1], as fit targets: predictions with
//! their parameter Jacobians (for Levenberg-Marquardt) and a closed-form start.
//!
//! - [`HighFidelity`], eq. 7 / problem (9): parameters `[alpha_rad, l0_m, beta_rad]`.
//! - [`LowFidelity`], eq. 10: parameters `[alpha_rad, l0_m]` (`beta = 0`).
//!
//! Closed-form start: eq. 7 rearranges to `1/z = a - b u_bar - c v_bar` with
//! `a = sin(alpha)/L`, `b = cos(alpha)/L`, `c = tan(beta)/L`, which is linear in `(a, b, c)`.
//! Its least-squares solution (an algebraic fit on `1/z`) starts the geometric fit on `z`.

use harvest_hw::alacs::AlacsExtrinsics;
use nalgebra::{SMatrix, SVector};

use super::sample::CalibrationSample;
use crate::triangulation::MIN_DENOMINATOR;

/// A depth model `z_hat(params; u_bar, v_bar)` with `N` parameters.
pub trait DepthModel<const N: usize> {
    /// Short name for logs and reports.
    const NAME: &'static str;

    /// `z_hat` and its gradient with respect to the parameters; `None` when the sample's ray
    /// does not meet the model's laser plane in front of the camera.
    fn predict(
        params: &SVector<f64, N>,
        sample: &CalibrationSample,
    ) -> Option<(f64, SVector<f64, N>)>;

    /// Closed-form parameters from the linear `1/z` form on `samples[indices]`; `None` when the
    /// samples do not determine them.
    fn linear_fit(samples: &[CalibrationSample], indices: &[usize]) -> Option<SVector<f64, N>>;

    /// The parameters as extrinsics (`beta = 0` for the low-fidelity model).
    fn to_extrinsics(params: &SVector<f64, N>) -> AlacsExtrinsics;
}

/// eq. 7 with `alpha`, `L0`, `beta`.
#[derive(Debug, Clone, Copy)]
pub struct HighFidelity;

/// eq. 10 with `alpha`, `L0`.
#[derive(Debug, Clone, Copy)]
pub struct LowFidelity;

impl DepthModel<3> for HighFidelity {
    const NAME: &'static str = "high-fidelity";

    fn predict(
        params: &SVector<f64, 3>,
        sample: &CalibrationSample,
    ) -> Option<(f64, SVector<f64, 3>)> {
        let (alpha, l0, beta) = (params[0], params[1], params[2]);
        let (sin_a, cos_a) = alpha.sin_cos();
        let tan_b = beta.tan();
        let denominator = sin_a - sample.u_bar * cos_a - sample.v_bar * tan_b;
        if denominator < MIN_DENOMINATOR || !denominator.is_finite() {
            return None;
        }
        let depth = l0 / denominator;
        let depth_per_denominator = -l0 / (denominator * denominator);
        let gradient = SVector::<f64, 3>::new(
            depth_per_denominator * (cos_a + sample.u_bar * sin_a),
            1.0 / denominator,
            depth_per_denominator * (-sample.v_bar * (1.0 + tan_b * tan_b)),
        );
        Some((depth, gradient))
    }

    fn linear_fit(samples: &[CalibrationSample], indices: &[usize]) -> Option<SVector<f64, 3>> {
        let mut normal = SMatrix::<f64, 3, 3>::zeros();
        let mut rhs = SVector::<f64, 3>::zeros();
        for &index in indices {
            let sample = &samples[index];
            let row = SVector::<f64, 3>::new(1.0, -sample.u_bar, -sample.v_bar);
            normal += row * row.transpose();
            rhs += row / sample.z_m;
        }
        let [a, b, c] = solve_well_conditioned(normal, rhs)?.into();
        let baseline = 1.0 / a.hypot(b);
        let alpha = a.atan2(b);
        let params = SVector::<f64, 3>::new(alpha, baseline, (c * baseline).atan());
        params.iter().all(|p| p.is_finite()).then_some(params)
    }

    fn to_extrinsics(params: &SVector<f64, 3>) -> AlacsExtrinsics {
        AlacsExtrinsics {
            alpha_rad: params[0],
            l0_m: params[1],
            beta_rad: params[2],
        }
    }
}

impl DepthModel<2> for LowFidelity {
    const NAME: &'static str = "low-fidelity";

    fn predict(
        params: &SVector<f64, 2>,
        sample: &CalibrationSample,
    ) -> Option<(f64, SVector<f64, 2>)> {
        let (alpha, l0) = (params[0], params[1]);
        let (sin_a, cos_a) = alpha.sin_cos();
        let denominator = sin_a - sample.u_bar * cos_a;
        if denominator < MIN_DENOMINATOR || !denominator.is_finite() {
            return None;
        }
        let gradient = SVector::<f64, 2>::new(
            -l0 / (denominator * denominator) * (cos_a + sample.u_bar * sin_a),
            1.0 / denominator,
        );
        Some((l0 / denominator, gradient))
    }

    fn linear_fit(samples: &[CalibrationSample], indices: &[usize]) -> Option<SVector<f64, 2>> {
        let mut normal = SMatrix::<f64, 2, 2>::zeros();
        let mut rhs = SVector::<f64, 2>::zeros();
        for &index in indices {
            let sample = &samples[index];
            let row = SVector::<f64, 2>::new(1.0, -sample.u_bar);
            normal += row * row.transpose();
            rhs += row / sample.z_m;
        }
        let [a, b] = solve_well_conditioned(normal, rhs)?.into();
        let params = SVector::<f64, 2>::new(a.atan2(b), 1.0 / a.hypot(b));
        params.iter().all(|p| p.is_finite()).then_some(params)
    }

    fn to_extrinsics(params: &SVector<f64, 2>) -> AlacsExtrinsics {
        AlacsExtrinsics {
            alpha_rad: params[0],
            l0_m: params[1],
            beta_rad: 0.0,
        }
    }
}

/// Smallest accepted Cholesky pivot relative to the largest diagonal entry of the normal
/// matrix. The columns `1, u_bar, v_bar` are O(1) and O(0.3), so a healthy system sits many
/// orders above it; samples on one image line give a pivot at rounding level.
const MIN_RELATIVE_PIVOT: f64 = 1e-10;

/// Solves the symmetric positive (semi-)definite system, refusing a (nearly) singular one.
fn solve_well_conditioned<const N: usize>(
    normal: SMatrix<f64, N, N>,
    rhs: SVector<f64, N>,
) -> Option<SVector<f64, N>> {
    let largest_diagonal = normal.diagonal().max();
    if largest_diagonal.is_nan() || largest_diagonal <= 0.0 {
        return None;
    }
    let factor = normal.cholesky()?;
    let smallest_pivot = factor.l_dirty().diagonal().map(|l| l * l).min();
    if smallest_pivot < MIN_RELATIVE_PIVOT * largest_diagonal {
        return None;
    }
    Some(factor.solve(&rhs))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact_samples(truth: &AlacsExtrinsics) -> Vec<CalibrationSample> {
        let mut samples = Vec::new();
        for (u_bar, v_bar) in [
            (-0.3, -0.2),
            (-0.1, 0.25),
            (0.05, 0.0),
            (0.15, -0.3),
            (-0.2, 0.1),
        ] {
            let z_m = crate::triangulation::high_fidelity_depth_m(
                truth.alpha_rad,
                truth.l0_m,
                truth.beta_rad,
                u_bar,
                v_bar,
            )
            .expect("in front");
            samples.push(CalibrationSample { u_bar, v_bar, z_m });
        }
        samples
    }

    #[test]
    fn linear_fit_is_exact_on_noise_free_samples() {
        let truth = AlacsExtrinsics::paper_table1();
        let samples = exact_samples(&truth);
        let params = HighFidelity::linear_fit(&samples, &[0, 1, 2, 3, 4]).expect("fit");
        let fitted = HighFidelity::to_extrinsics(&params);
        assert!((fitted.alpha_rad - truth.alpha_rad).abs() < 1e-12);
        assert!((fitted.l0_m - truth.l0_m).abs() < 1e-12);
        assert!((fitted.beta_rad - truth.beta_rad).abs() < 1e-12);
    }

    #[test]
    fn gradients_match_finite_differences() {
        let sample = CalibrationSample {
            u_bar: -0.12,
            v_bar: 0.27,
            z_m: 1.0,
        };
        let params = SVector::<f64, 3>::new(0.33, 0.38, 0.012);
        let (_, gradient) = HighFidelity::predict(&params, &sample).expect("valid");
        for k in 0..3 {
            let mut step = SVector::<f64, 3>::zeros();
            step[k] = 1e-7;
            let (plus, _) = HighFidelity::predict(&(params + step), &sample).expect("valid");
            let (minus, _) = HighFidelity::predict(&(params - step), &sample).expect("valid");
            let numeric = (plus - minus) / 2e-7;
            assert!(
                (numeric - gradient[k]).abs() < 1e-6 * numeric.abs().max(1.0),
                "{k}"
            );
        }
        let low = SVector::<f64, 2>::new(0.33, 0.38);
        let (_, gradient) = LowFidelity::predict(&low, &sample).expect("valid");
        let step = SVector::<f64, 2>::new(1e-7, 0.0);
        let (plus, _) = LowFidelity::predict(&(low + step), &sample).expect("valid");
        let (minus, _) = LowFidelity::predict(&(low - step), &sample).expect("valid");
        assert!(((plus - minus) / 2e-7 - gradient[0]).abs() < 1e-6);
    }

    #[test]
    fn samples_on_one_image_line_are_degenerate() {
        // Four samples on one line of the image: the 3x3 normal matrix has rank 2.
        let samples: Vec<CalibrationSample> = (0..4)
            .map(|k| CalibrationSample {
                u_bar: -0.1 + 0.001 * k as f64,
                v_bar: 0.1 * k as f64,
                z_m: 0.8 + 0.05 * k as f64,
            })
            .collect();
        assert!(HighFidelity::linear_fit(&samples, &[0, 1, 2, 3]).is_none());
    }
}
