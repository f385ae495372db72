//! Order statistics of error and timing samples.

use serde::Serialize;

/// Nearest-rank quantile of ascending-sorted samples: the smallest sample such that at least a
/// fraction `q` of the samples are at or below it (`sorted[ceil(q n) - 1]`). `None` when empty.
pub fn nearest_rank(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let rank = (q.clamp(0.0, 1.0) * sorted.len() as f64).ceil() as usize;
    Some(sorted[rank.clamp(1, sorted.len()) - 1])
}

/// Summary of a set of samples in one unit (the field names of the users carry the unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    pub count: usize,
    pub mean: Option<f64>,
    pub median: Option<f64>,
    /// Nearest-rank 95th percentile.
    pub p95: Option<f64>,
    pub max: Option<f64>,
}

impl Summary {
    /// Summarizes `samples` (sorted in place; non-finite samples sort last by total order).
    pub fn of(samples: &mut [f64]) -> Self {
        samples.sort_by(f64::total_cmp);
        let count = samples.len();
        let mean = (count > 0).then(|| samples.iter().sum::<f64>() / count as f64);
        Self {
            count,
            mean,
            median: nearest_rank(samples, 0.5),
            p95: nearest_rank(samples, 0.95),
            max: samples.last().copied(),
        }
    }
}

/// `numerator / denominator`, `None` when the denominator is zero.
pub fn ratio(numerator: usize, denominator: usize) -> Option<f64> {
    (denominator > 0).then(|| numerator as f64 / denominator as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_known_answers() {
        let sorted: Vec<f64> = (1..=20).map(f64::from).collect();
        assert_eq!(nearest_rank(&sorted, 0.5), Some(10.0));
        assert_eq!(nearest_rank(&sorted, 0.95), Some(19.0));
        assert_eq!(nearest_rank(&sorted, 1.0), Some(20.0));
        assert_eq!(nearest_rank(&sorted, 0.0), Some(1.0));
        assert_eq!(nearest_rank(&[7.0], 0.95), Some(7.0));
        assert_eq!(nearest_rank(&[], 0.5), None);
    }

    #[test]
    fn summary_of_unsorted_samples() {
        let mut samples = vec![3.0, 1.0, 2.0, 10.0];
        let summary = Summary::of(&mut samples);
        assert_eq!(summary.count, 4);
        assert_eq!(summary.mean, Some(4.0));
        assert_eq!(summary.median, Some(2.0));
        assert_eq!(summary.p95, Some(10.0));
        assert_eq!(summary.max, Some(10.0));
        assert_eq!(Summary::of(&mut []).median, None);
        assert_eq!(ratio(1, 4), Some(0.25));
        assert_eq!(ratio(0, 0), None);
    }
}
