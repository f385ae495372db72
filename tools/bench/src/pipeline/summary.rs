//! Exact percentiles of a run's samples (a pipeline run has thousands, not millions, so they
//! are kept and sorted instead of binned).

use serde::Serialize;

/// The raw samples of one distribution, in nanoseconds.
#[derive(Debug, Clone, Default)]
pub struct Samples(Vec<u64>);

/// Percentiles of one distribution, nearest-rank (the smallest sample with at least that
/// fraction of samples at or below it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    pub samples: u64,
    /// The median.
    pub p50_ns: u64,
    pub p90_ns: u64,
    pub p99_ns: u64,
    pub max_ns: u64,
    pub mean_ns: f64,
}

impl Samples {
    pub fn push(&mut self, value_ns: u64) {
        self.0.push(value_ns);
    }

    pub fn len(&self) -> usize {
        self.0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// None for no samples.
    pub fn summary(&self) -> Option<Summary> {
        if self.0.is_empty() {
            return None;
        }
        let mut sorted = self.0.clone();
        sorted.sort_unstable();
        let rank = |q: f64| {
            let index = (q * sorted.len() as f64).ceil() as usize;
            sorted[index.clamp(1, sorted.len()) - 1]
        };
        Some(Summary {
            samples: sorted.len() as u64,
            p50_ns: rank(0.5),
            p90_ns: rank(0.9),
            p99_ns: rank(0.99),
            max_ns: sorted[sorted.len() - 1],
            mean_ns: sorted.iter().map(|&v| v as f64).sum::<f64>() / sorted.len() as f64,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles_of_one_to_a_hundred() {
        let mut samples = Samples::default();
        assert!(samples.summary().is_none());
        for value in (1..=100u64).rev() {
            samples.push(value);
        }
        let summary = samples.summary().expect("samples");
        assert_eq!(summary.samples, 100);
        assert_eq!(summary.p50_ns, 50);
        assert_eq!(summary.p90_ns, 90);
        assert_eq!(summary.p99_ns, 99);
        assert_eq!(summary.max_ns, 100);
        assert!((summary.mean_ns - 50.5).abs() < 1e-12);
    }

    #[test]
    fn one_sample_is_every_percentile() {
        let mut samples = Samples::default();
        samples.push(7);
        let summary = samples.summary().expect("sample");
        assert_eq!((summary.p50_ns, summary.p99_ns, summary.max_ns), (7, 7, 7));
    }
}
