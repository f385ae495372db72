//! Levenberg-Marquardt for [alacs problem 9]: minimise `sum (z_i - z_hat_i)^2` over the
//! model parameters, on a subset of the samples. Fixed-size (`N` = 2 or 3) normal equations,
//! so one iteration allocates nothing.

use nalgebra::{SMatrix, SVector};

use super::model::DepthModel;
use super::sample::CalibrationSample;

/// Stopping rules of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    /// Most accepted-or-rejected steps.
    pub max_iterations: usize,
    /// Stop once a step changes every parameter by less than this (relative to its size,
    /// or absolutely below 1).
    pub step_tolerance: f64,
    /// Initial damping, relative to the diagonal of `J^T J`.
    pub initial_damping: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            step_tolerance: 1e-12,
            initial_damping: 1e-3,
        }
    }
}

/// The minimiser found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmSolution<const N: usize> {
    pub params: SVector<f64, N>,
    /// `sum (z_i - z_hat_i)^2` at `params`, m^2.
    pub cost_m2: f64,
    pub iterations: usize,
    /// True when the step tolerance was reached (not the iteration limit).
    pub converged: bool,
}

/// Why the fit could not run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LmFailure {
    /// Some sample's ray misses the starting model's plane (no prediction).
    InvalidStart,
    /// `J^T J` is singular even with damping (the subset does not determine the parameters).
    Singular,
}

/// Sum of squared depth residuals over `indices`; `None` if any prediction fails.
pub fn cost_m2<const N: usize, M: DepthModel<N>>(
    params: &SVector<f64, N>,
    samples: &[CalibrationSample],
    indices: &[usize],
) -> Option<f64> {
    let mut cost = 0.0;
    for &index in indices {
        let (depth, _) = M::predict(params, &samples[index])?;
        cost += (samples[index].z_m - depth).powi(2);
    }
    Some(cost)
}

/// Minimises the depth residuals of `samples[indices]` from `start` (Marquardt's scaling:
/// damping `lambda * diag(J^T J)`; a step that does not lower the cost is refused and the
/// damping raised tenfold, an accepted one lowers it threefold).
pub fn levenberg_marquardt<const N: usize, M: DepthModel<N>>(
    samples: &[CalibrationSample],
    indices: &[usize],
    start: SVector<f64, N>,
    options: &LmOptions,
) -> Result<LmSolution<N>, LmFailure> {
    let mut params = start;
    let mut cost = cost_m2::<N, M>(&params, samples, indices).ok_or(LmFailure::InvalidStart)?;
    let mut damping = options.initial_damping;
    let mut iterations = 0;
    let mut converged = false;
    let (mut jtj, mut jtr) =
        normal_equations::<N, M>(&params, samples, indices).ok_or(LmFailure::InvalidStart)?;
    while iterations < options.max_iterations {
        iterations += 1;
        let mut damped = jtj;
        for k in 0..N {
            damped[(k, k)] += damping * jtj[(k, k)].max(1e-12);
        }
        let Some(factor) = damped.cholesky() else {
            if damping > 1e12 {
                return Err(LmFailure::Singular);
            }
            damping *= 10.0;
            continue;
        };
        let step = factor.solve(&(-jtr));
        let candidate = params + step;
        match cost_m2::<N, M>(&candidate, samples, indices) {
            Some(candidate_cost) if candidate_cost <= cost => {
                params = candidate;
                let improvement = cost - candidate_cost;
                cost = candidate_cost;
                damping = (damping / 3.0).max(1e-15);
                let small_step = step
                    .iter()
                    .zip(params.iter())
                    .all(|(s, p)| s.abs() <= options.step_tolerance * p.abs().max(1.0));
                if small_step || improvement <= f64::EPSILON * cost {
                    converged = true;
                    break;
                }
                (jtj, jtr) = normal_equations::<N, M>(&params, samples, indices)
                    .ok_or(LmFailure::InvalidStart)?;
            }
            _ => {
                if damping > 1e12 {
                    // No step lowers the cost any more: we are at the minimum to precision.
                    converged = true;
                    break;
                }
                damping *= 10.0;
            }
        }
    }
    Ok(LmSolution {
        params,
        cost_m2: cost,
        iterations,
        converged,
    })
}

/// `J^T J` and `J^T r` for residuals `r_i = z_i - z_hat_i` (so `J = -d z_hat / d params`).
fn normal_equations<const N: usize, M: DepthModel<N>>(
    params: &SVector<f64, N>,
    samples: &[CalibrationSample],
    indices: &[usize],
) -> Option<(SMatrix<f64, N, N>, SVector<f64, N>)> {
    let mut jtj = SMatrix::<f64, N, N>::zeros();
    let mut jtr = SVector::<f64, N>::zeros();
    for &index in indices {
        let sample = &samples[index];
        let (depth, gradient) = M::predict(params, sample)?;
        let residual = sample.z_m - depth;
        jtj += gradient * gradient.transpose();
        jtr -= gradient * residual;
    }
    Some((jtj, jtr))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::model::HighFidelity;

    #[test]
    fn converges_to_the_truth_from_a_rough_start() {
        let truth = SVector::<f64, 3>::new(19.07_f64.to_radians(), 0.38198, 0.69_f64.to_radians());
        let mut samples = Vec::new();
        for k in 0..12 {
            let u_bar = -0.3 + 0.04 * k as f64;
            let v_bar = 0.25 * ((k % 3) as f64 - 1.0);
            let probe = CalibrationSample {
                u_bar,
                v_bar,
                z_m: 1.0,
            };
            let (z_m, _) = HighFidelity::predict(&truth, &probe).expect("in front");
            samples.push(CalibrationSample { u_bar, v_bar, z_m });
        }
        let indices: Vec<usize> = (0..samples.len()).collect();
        let start = SVector::<f64, 3>::new(0.30, 0.35, 0.0);
        let solution = levenberg_marquardt::<3, HighFidelity>(
            &samples,
            &indices,
            start,
            &LmOptions::default(),
        )
        .expect("fit");
        assert!(solution.converged);
        assert!(
            (solution.params - truth).norm() < 1e-9,
            "{:?}",
            solution.params
        );
        assert!(solution.cost_m2 < 1e-20);
    }
}
