//! The four calibration methods compared in [alacs sec. 5.1] (Tables 1-2), each timed.
//!
//! | # | model | data |
//! |---|---|---|
//! | 1 | low-fidelity (eq. 10) | all samples |
//! | 2 | low-fidelity | RANSAC (Algorithm 1) |
//! | 3 | high-fidelity (eq. 7) | all samples |
//! | 4 | high-fidelity | RANSAC (Algorithm 1): the paper's method |

use std::time::Instant;

use harvest_hw::alacs::AlacsExtrinsics;
use serde::{Deserialize, Serialize};

use super::error::CalibrationError;
use super::fit::{RansacOptions, fit_all, fit_ransac};
use super::least_squares::LmOptions;
use super::model::{DepthModel, HighFidelity, LowFidelity};
use super::sample::{CalibrationSample, validate_samples};
use crate::triangulation::high_fidelity_depth_m;

/// One of the paper's four calibration methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CalibrationMethod {
    LowFidelityAllData,
    LowFidelityRansac,
    HighFidelityAllData,
    HighFidelityRansac,
}

/// A row of the paper's Tables 1 and 2, for side-by-side reporting.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperRow {
    pub alpha_deg: f64,
    pub l0_mm: f64,
    pub beta_deg: Option<f64>,
    pub mean_abs_error_mm: f64,
    /// MATLAB on an i7-10710U (Table 2).
    pub time_ms: f64,
}

impl CalibrationMethod {
    /// In the paper's order.
    pub const ALL: [Self; 4] = [
        Self::LowFidelityAllData,
        Self::LowFidelityRansac,
        Self::HighFidelityAllData,
        Self::HighFidelityRansac,
    ];

    /// The paper's method number.
    pub fn number(self) -> u8 {
        match self {
            Self::LowFidelityAllData => 1,
            Self::LowFidelityRansac => 2,
            Self::HighFidelityAllData => 3,
            Self::HighFidelityRansac => 4,
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Self::LowFidelityAllData => "low-fidelity + all data",
            Self::LowFidelityRansac => "low-fidelity + RANSAC",
            Self::HighFidelityAllData => "high-fidelity + all data",
            Self::HighFidelityRansac => "high-fidelity + RANSAC",
        }
    }

    pub fn is_high_fidelity(self) -> bool {
        matches!(self, Self::HighFidelityAllData | Self::HighFidelityRansac)
    }

    /// What the paper reports for this method (Tables 1-2).
    pub fn paper_row(self) -> PaperRow {
        let (alpha_deg, l0_mm, beta_deg, mean_abs_error_mm, time_s) = match self {
            Self::LowFidelityAllData => (19.03, 382.83, None, 4.91, 0.015),
            Self::LowFidelityRansac => (19.28, 386.37, None, 3.80, 1.741),
            Self::HighFidelityAllData => (19.01, 381.09, Some(0.73), 1.84, 0.023),
            Self::HighFidelityRansac => (19.07, 381.98, Some(0.69), 0.39, 1.824),
        };
        PaperRow {
            alpha_deg,
            l0_mm,
            beta_deg,
            mean_abs_error_mm,
            time_ms: time_s * 1e3,
        }
    }
}

/// Options shared by the methods.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationOptions {
    /// Algorithm 1's `k_max`, `epsilon`, its per-model scaling and draw seed (methods 2 and 4).
    /// Default: 200 hypotheses, epsilon 2 mm raised to 2.5 least-median-of-squares standard
    /// deviations of the model (Rousseeuw's cut-off), which leaves the high-fidelity model at
    /// 2 mm and gives the low-fidelity model a threshold above its own structural error.
    pub ransac: RansacOptions,
    pub lm: LmOptions,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            ransac: RansacOptions {
                iterations: 200,
                epsilon_m: 0.002,
                scale_sigmas: 2.5,
                seed: 1,
            },
            lm: LmOptions::default(),
        }
    }
}

/// Parameters from one method.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub method: CalibrationMethod,
    /// `beta_rad = 0` for the low-fidelity methods.
    pub extrinsics: AlacsExtrinsics,
    /// Samples of the final least-squares fit (all, or the RANSAC inliers).
    pub used: Vec<usize>,
    /// RANSAC's inlier threshold, m (`None` for the all-data methods).
    pub threshold_m: Option<f64>,
}

/// Runs one method on validated samples.
pub fn calibrate(
    samples: &[CalibrationSample],
    method: CalibrationMethod,
    options: &CalibrationOptions,
) -> Result<Calibration, CalibrationError> {
    validate_samples(samples)?;
    let (extrinsics, used, threshold_m) = match method {
        CalibrationMethod::LowFidelityAllData => {
            let outcome = fit_all::<2, LowFidelity>(samples, &options.lm)?;
            let extrinsics = LowFidelity::to_extrinsics(&outcome.params);
            (extrinsics, outcome.used, outcome.threshold_m)
        }
        CalibrationMethod::LowFidelityRansac => {
            let outcome = fit_ransac::<2, LowFidelity>(samples, &options.ransac, &options.lm)?;
            let extrinsics = LowFidelity::to_extrinsics(&outcome.params);
            (extrinsics, outcome.used, outcome.threshold_m)
        }
        CalibrationMethod::HighFidelityAllData => {
            let outcome = fit_all::<3, HighFidelity>(samples, &options.lm)?;
            let extrinsics = HighFidelity::to_extrinsics(&outcome.params);
            (extrinsics, outcome.used, outcome.threshold_m)
        }
        CalibrationMethod::HighFidelityRansac => {
            let outcome = fit_ransac::<3, HighFidelity>(samples, &options.ransac, &options.lm)?;
            let extrinsics = HighFidelity::to_extrinsics(&outcome.params);
            (extrinsics, outcome.used, outcome.threshold_m)
        }
    };
    if !(extrinsics.l0_m.is_finite() && extrinsics.l0_m > 0.0) {
        return Err(CalibrationError::Degenerate {
            detail: format!("fit ended at L0 = {} m", extrinsics.l0_m),
        });
    }
    Ok(Calibration {
        method,
        extrinsics,
        used,
        threshold_m,
    })
}

/// Mean `|z - z_hat|` (m) over `samples[indices]` with `extrinsics` at the calibration slide
/// position (`L = L0`); a sample the model cannot predict counts as infinitely wrong.
pub fn mean_abs_depth_error_m(
    samples: &[CalibrationSample],
    indices: &[usize],
    extrinsics: &AlacsExtrinsics,
) -> f64 {
    if indices.is_empty() {
        return f64::NAN;
    }
    let total: f64 = indices
        .iter()
        .map(|&index| {
            let sample = &samples[index];
            high_fidelity_depth_m(
                extrinsics.alpha_rad,
                extrinsics.l0_m,
                extrinsics.beta_rad,
                sample.u_bar,
                sample.v_bar,
            )
            .map_or(f64::INFINITY, |depth| (sample.z_m - depth).abs())
        })
        .sum();
    total / indices.len() as f64
}

/// One row of the comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodResult {
    pub method: CalibrationMethod,
    pub number: u8,
    pub label: &'static str,
    pub alpha_deg: f64,
    pub l0_mm: f64,
    /// `None` for the low-fidelity methods (the paper's "/").
    pub beta_deg: Option<f64>,
    /// Mean `|z - z_hat|` over the evaluation set, mm (Table 1's column).
    pub mean_abs_error_mm: f64,
    /// Mean `|z - z_hat|` over every sample, outliers included, mm.
    pub mean_abs_error_all_mm: f64,
    /// Samples in the final fit.
    pub used_samples: usize,
    /// Mean `|z - z_hat|` over the samples of the final fit, mm: the fit's own residual (all
    /// samples for methods 1 and 3, the inliers for 2 and 4).
    pub mean_abs_error_used_mm: f64,
    /// RANSAC's inlier threshold, mm (`None` for methods 1 and 3).
    pub epsilon_mm: Option<f64>,
    /// Wall time of the method (validation, fit), ms.
    pub time_ms: f64,
    pub paper: PaperRow,
}

impl MethodResult {
    pub fn extrinsics(&self) -> AlacsExtrinsics {
        AlacsExtrinsics {
            alpha_rad: self.alpha_deg.to_radians(),
            l0_m: self.l0_mm * 1e-3,
            beta_rad: self.beta_deg.unwrap_or(0.0).to_radians(),
        }
    }
}

/// Which samples the mean error column is computed on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EvaluationSet {
    /// Samples the generator did not corrupt (known only for generated data).
    CleanSamples,
    /// Every sample (real data: outliers are unknown).
    AllSamples,
}

/// The Table-1-style comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    pub samples: usize,
    pub evaluation_set: EvaluationSet,
    pub evaluation_samples: usize,
    pub epsilon_mm: f64,
    /// RANSAC thresholds are `max(epsilon, this x LMedS sigma)` (0: epsilon alone).
    pub epsilon_scale_sigmas: f64,
    pub iterations: usize,
    pub methods: Vec<MethodResult>,
}

impl CalibrationReport {
    pub fn method(&self, method: CalibrationMethod) -> Option<&MethodResult> {
        self.methods.iter().find(|row| row.method == method)
    }
}

/// Runs the four methods on the same samples and reports Table 1 (parameters, mean error) and
/// Table 2 (time). `clean` marks the samples the error column is computed on (generator labels);
/// `None` means all samples.
pub fn compare_methods(
    samples: &[CalibrationSample],
    clean: Option<&[bool]>,
    options: &CalibrationOptions,
) -> Result<CalibrationReport, CalibrationError> {
    validate_samples(samples)?;
    let all: Vec<usize> = (0..samples.len()).collect();
    let (evaluation_set, evaluation): (EvaluationSet, Vec<usize>) = match clean {
        Some(clean) if clean.len() == samples.len() => (
            EvaluationSet::CleanSamples,
            all.iter().copied().filter(|&index| clean[index]).collect(),
        ),
        _ => (EvaluationSet::AllSamples, all.clone()),
    };
    let mut methods = Vec::with_capacity(CalibrationMethod::ALL.len());
    for method in CalibrationMethod::ALL {
        let started = Instant::now();
        let calibration = calibrate(samples, method, options)?;
        let time_ms = started.elapsed().as_secs_f64() * 1e3;
        let extrinsics = calibration.extrinsics;
        methods.push(MethodResult {
            method,
            number: method.number(),
            label: method.label(),
            alpha_deg: extrinsics.alpha_rad.to_degrees(),
            l0_mm: extrinsics.l0_m * 1e3,
            beta_deg: method
                .is_high_fidelity()
                .then(|| extrinsics.beta_rad.to_degrees()),
            mean_abs_error_mm: mean_abs_depth_error_m(samples, &evaluation, &extrinsics) * 1e3,
            mean_abs_error_all_mm: mean_abs_depth_error_m(samples, &all, &extrinsics) * 1e3,
            used_samples: calibration.used.len(),
            mean_abs_error_used_mm: mean_abs_depth_error_m(samples, &calibration.used, &extrinsics)
                * 1e3,
            epsilon_mm: calibration.threshold_m.map(|t| t * 1e3),
            time_ms,
            paper: method.paper_row(),
        });
    }
    Ok(CalibrationReport {
        samples: samples.len(),
        evaluation_set,
        evaluation_samples: evaluation.len(),
        epsilon_mm: options.ransac.epsilon_m * 1e3,
        epsilon_scale_sigmas: options.ransac.scale_sigmas,
        iterations: options.ransac.iterations,
        methods,
    })
}

impl std::fmt::Display for CalibrationReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let evaluated = match self.evaluation_set {
            EvaluationSet::CleanSamples => "clean samples (generator labels)",
            EvaluationSet::AllSamples => "all samples",
        };
        writeln!(
            f,
            "ALACS laser calibration: {} samples; mean|dz| over {} {}, all|dz| over every sample, \
             fit|dz| over the samples of the final fit; RANSAC epsilon max({} mm, {} LMedS sigma), \
             {} hypotheses",
            self.samples,
            self.evaluation_samples,
            evaluated,
            self.epsilon_mm,
            self.epsilon_scale_sigmas,
            self.iterations
        )?;
        writeln!(
            f,
            "{:<30} {:>10} {:>9} {:>10} {:>13} {:>11} {:>11} {:>5} {:>8} {:>10}",
            "method",
            "alpha deg",
            "L0 mm",
            "beta deg",
            "mean|dz| mm",
            "all|dz| mm",
            "fit|dz| mm",
            "used",
            "eps mm",
            "time ms"
        )?;
        for row in &self.methods {
            writeln!(
                f,
                "{:<30} {:>10.2} {:>9.2} {:>10} {:>13.2} {:>11.2} {:>11.2} {:>5} {:>8} {:>10.3}",
                format!("{} {}", row.number, row.label),
                row.alpha_deg,
                row.l0_mm,
                row.beta_deg.map_or("/".to_string(), |b| format!("{b:.2}")),
                row.mean_abs_error_mm,
                row.mean_abs_error_all_mm,
                row.mean_abs_error_used_mm,
                row.used_samples,
                row.epsilon_mm
                    .map_or("/".to_string(), |e| format!("{e:.2}")),
                row.time_ms
            )?;
        }
        writeln!(f, "paper (Tables 1-2, MATLAB on an i7-10710U):")?;
        for row in &self.methods {
            let paper = row.paper;
            writeln!(
                f,
                "{:<30} {:>10.2} {:>9.2} {:>10} {:>13.2} {:>11} {:>11} {:>5} {:>8} {:>10.0}",
                format!("{} {}", row.number, row.label),
                paper.alpha_deg,
                paper.l0_mm,
                paper
                    .beta_deg
                    .map_or("/".to_string(), |b| format!("{b:.2}")),
                paper.mean_abs_error_mm,
                "",
                "",
                "",
                "",
                paper.time_ms
            )?;
        }
        Ok(())
    }
}
