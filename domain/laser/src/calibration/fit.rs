//! The two ways of solving [alacs problem 9] with a model: on all samples, and robustly
//! with RANSAC (Algorithm 1).

use nalgebra::SVector;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::error::CalibrationError;
use super::least_squares::{LmFailure, LmOptions, levenberg_marquardt};
use super::model::DepthModel;
use super::sample::{CalibrationSample, MIN_SAMPLES};

/// Algorithm 1's inputs besides the samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacOptions {
    /// `k_max`: hypotheses drawn.
    pub iterations: usize,
    /// `epsilon`: a sample is an inlier when `|z - z_hat| <= epsilon`, m (the floor of the
    /// threshold when `scale_sigmas > 0`).
    pub epsilon_m: f64,
    /// 0: the threshold is `epsilon` (Algorithm 1 as written). Otherwise the threshold is
    /// `max(epsilon, scale_sigmas * sigma)`, with `sigma` the least-median-of-squares scale of
    /// the model over the same hypotheses (see [`lmeds_sigma_m`]): a model that cannot fit clean
    /// data to within `epsilon` (the low-fidelity model, whose dropped `v_bar tan(beta)` term
    /// costs several mm at 1.2 m) would otherwise have most good samples voted out with the
    /// outliers.
    pub scale_sigmas: f64,
    /// Seed of the sample draws; the same seed gives the same result.
    pub seed: u64,
}

/// Gaussian consistency factor of the median absolute residual.
const MEDIAN_TO_SIGMA: f64 = 1.4826;

/// The least-median-of-squares scale (Rousseeuw 1984) of the smallest median absolute residual
/// `median_abs_m` found over the hypotheses: `1.4826 (1 + 5 / (n - p)) median`, with `n`
/// samples and `p` model parameters. It ignores up to half the samples, so the outliers do not
/// inflate it.
pub fn lmeds_sigma_m(median_abs_m: f64, samples: usize, parameters: usize) -> f64 {
    let dof = samples.saturating_sub(parameters).max(1) as f64;
    MEDIAN_TO_SIGMA * (1.0 + 5.0 / dof) * median_abs_m
}

/// A fitted parameter vector and the samples it was fitted on.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOutcome<const N: usize> {
    pub params: SVector<f64, N>,
    /// Indices of the samples of the final least-squares fit.
    pub used: Vec<usize>,
    /// The inlier threshold RANSAC verified with, m; `None` for a fit on all samples.
    pub threshold_m: Option<f64>,
}

/// Least squares (9) on every sample: closed-form start, then Levenberg-Marquardt.
pub fn fit_all<const N: usize, M: DepthModel<N>>(
    samples: &[CalibrationSample],
    lm: &LmOptions,
) -> Result<FitOutcome<N>, CalibrationError> {
    let used: Vec<usize> = (0..samples.len()).collect();
    let params = fit_subset::<N, M>(samples, &used, None, lm)?;
    Ok(FitOutcome {
        params,
        used,
        threshold_m: None,
    })
}

/// Algorithm 1: draw `k_max` random 4-sample subsets, fit each (hypothesis), count the samples
/// within `epsilon` of it, keep the largest inlier set, and fit once more on it.
///
/// With `scale_sigmas > 0` the hypotheses are drawn and fitted first, the threshold is set from
/// their least-median-of-squares scale, and then each is verified against it (same draws, same
/// order: a tie keeps the earlier hypothesis).
///
/// A 4-sample subset that does not determine the parameters (e.g. all from one board) yields no
/// hypothesis and counts as a drawn iteration.
pub fn fit_ransac<const N: usize, M: DepthModel<N>>(
    samples: &[CalibrationSample],
    options: &RansacOptions,
    lm: &LmOptions,
) -> Result<FitOutcome<N>, CalibrationError> {
    if options.iterations == 0 {
        return Err(CalibrationError::InvalidOption {
            name: "iterations",
            value: 0.0,
        });
    }
    if !(options.epsilon_m.is_finite() && options.epsilon_m > 0.0) {
        return Err(CalibrationError::InvalidOption {
            name: "epsilon_m",
            value: options.epsilon_m,
        });
    }
    if samples.len() < MIN_SAMPLES {
        return Err(CalibrationError::TooFewSamples {
            got: samples.len(),
            needed: MIN_SAMPLES,
        });
    }
    if !(options.scale_sigmas.is_finite() && options.scale_sigmas >= 0.0) {
        return Err(CalibrationError::InvalidOption {
            name: "scale_sigmas",
            value: options.scale_sigmas,
        });
    }
    let mut rng = SmallRng::seed_from_u64(options.seed);
    // 1. Hypothesis generation.
    let mut hypotheses: Vec<SVector<f64, N>> = Vec::with_capacity(options.iterations);
    let mut failed_hypotheses = 0_usize;
    for _ in 0..options.iterations {
        let subset = draw_distinct::<MIN_SAMPLES>(&mut rng, samples.len());
        match fit_subset::<N, M>(samples, &subset, None, lm) {
            Ok(hypothesis) => hypotheses.push(hypothesis),
            Err(_) => failed_hypotheses += 1,
        }
    }
    let mut residuals: Vec<f64> = Vec::with_capacity(samples.len());
    let epsilon_m = if options.scale_sigmas > 0.0 {
        let mut smallest_median_m = f64::INFINITY;
        for hypothesis in &hypotheses {
            residuals.clear();
            residuals.extend(samples.iter().map(|sample| {
                M::predict(hypothesis, sample)
                    .map_or(f64::INFINITY, |(depth, _)| (sample.z_m - depth).abs())
            }));
            let middle = residuals.len() / 2;
            let (_, median, _) = residuals.select_nth_unstable_by(middle, f64::total_cmp);
            smallest_median_m = smallest_median_m.min(*median);
        }
        let sigma_m = lmeds_sigma_m(smallest_median_m, samples.len(), N);
        if sigma_m.is_finite() {
            options.epsilon_m.max(options.scale_sigmas * sigma_m)
        } else {
            options.epsilon_m
        }
    } else {
        options.epsilon_m
    };
    // 2. Verification.
    let mut best: Option<SVector<f64, N>> = None;
    let mut best_inliers: Vec<usize> = Vec::with_capacity(samples.len());
    let mut inliers: Vec<usize> = Vec::with_capacity(samples.len());
    for hypothesis in hypotheses {
        inliers.clear();
        inliers.extend((0..samples.len()).filter(|&index| {
            M::predict(&hypothesis, &samples[index])
                .is_some_and(|(depth, _)| (samples[index].z_m - depth).abs() <= epsilon_m)
        }));
        if inliers.len() > best_inliers.len() {
            std::mem::swap(&mut inliers, &mut best_inliers);
            best = Some(hypothesis);
        }
    }
    tracing::debug!(
        model = M::NAME,
        inliers = best_inliers.len(),
        samples = samples.len(),
        failed_hypotheses,
        epsilon_m,
        "RANSAC consensus"
    );
    let needed = MIN_SAMPLES.max(N + 1);
    let Some(hypothesis) = best.filter(|_| best_inliers.len() >= needed) else {
        return Err(CalibrationError::NoConsensus {
            best_inliers: best_inliers.len(),
            needed,
            epsilon_m,
        });
    };
    // Final estimate on the inliers of the best hypothesis, started from it.
    let params = fit_subset::<N, M>(samples, &best_inliers, Some(hypothesis), lm)?;
    Ok(FitOutcome {
        params,
        used: best_inliers,
        threshold_m: Some(epsilon_m),
    })
}

/// Least squares on `samples[indices]`, from `start` or from the closed-form solution.
fn fit_subset<const N: usize, M: DepthModel<N>>(
    samples: &[CalibrationSample],
    indices: &[usize],
    start: Option<SVector<f64, N>>,
    lm: &LmOptions,
) -> Result<SVector<f64, N>, CalibrationError> {
    let start = match start {
        Some(start) => start,
        None => M::linear_fit(samples, indices).ok_or_else(|| CalibrationError::Degenerate {
            detail: format!(
                "the {} samples do not determine the {} model (all on one image line?)",
                indices.len(),
                M::NAME
            ),
        })?,
    };
    match levenberg_marquardt::<N, M>(samples, indices, start, lm) {
        Ok(solution) => Ok(solution.params),
        Err(LmFailure::Singular) => Err(CalibrationError::Degenerate {
            detail: format!("the {} model's normal equations are singular", M::NAME),
        }),
        Err(LmFailure::InvalidStart) => Err(CalibrationError::Degenerate {
            detail: format!(
                "a sample's ray misses the {} model's laser plane at the start",
                M::NAME
            ),
        }),
    }
}

/// `K` distinct indices in `0..n` (`n >= K`), uniformly.
fn draw_distinct<const K: usize>(rng: &mut SmallRng, n: usize) -> [usize; K] {
    let mut picks = [0; K];
    let mut filled = 0;
    while filled < K {
        let candidate = rng.random_range(0..n);
        if !picks[..filled].contains(&candidate) {
            picks[filled] = candidate;
            filled += 1;
        }
    }
    picks
}
