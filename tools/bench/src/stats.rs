//! Latency percentiles (HDR histogram), throughput, and medians over repeated runs.

use crate::error::BenchError;
use hdrhistogram::Histogram;
use serde::Serialize;

/// Highest latency the histogram resolves (100 s); larger values are clamped to it.
const HISTOGRAM_MAX_NS: u64 = 100_000_000_000;
/// Significant decimal digits kept by the histogram (0.1 % resolution).
const HISTOGRAM_DIGITS: u8 = 3;

/// A latency histogram in nanoseconds.
pub fn latency_histogram() -> Result<Histogram<u64>, BenchError> {
    Histogram::new_with_bounds(1, HISTOGRAM_MAX_NS, HISTOGRAM_DIGITS).map_err(|error| {
        BenchError::Histogram {
            reason: error.to_string(),
        }
    })
}

/// One-way latency distribution of one run (or the per-field median of several).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct LatencySummary {
    pub samples: u64,
    pub p50_ns: u64,
    pub p90_ns: u64,
    pub p99_ns: u64,
    pub p999_ns: u64,
    pub max_ns: u64,
    pub mean_ns: f64,
}

impl LatencySummary {
    pub fn from_histogram(histogram: &Histogram<u64>) -> Self {
        Self {
            samples: histogram.len(),
            p50_ns: histogram.value_at_quantile(0.5),
            p90_ns: histogram.value_at_quantile(0.9),
            p99_ns: histogram.value_at_quantile(0.99),
            p999_ns: histogram.value_at_quantile(0.999),
            max_ns: histogram.max(),
            mean_ns: histogram.mean(),
        }
    }

    /// The median of each field over `runs` (None for no runs).
    pub fn median_of(runs: &[Self]) -> Option<Self> {
        if runs.is_empty() {
            return None;
        }
        let pick = |field: fn(&Self) -> u64| median_u64(runs.iter().map(field).collect());
        Some(Self {
            samples: pick(|r| r.samples),
            p50_ns: pick(|r| r.p50_ns),
            p90_ns: pick(|r| r.p90_ns),
            p99_ns: pick(|r| r.p99_ns),
            p999_ns: pick(|r| r.p999_ns),
            max_ns: pick(|r| r.max_ns),
            mean_ns: median_f64(runs.iter().map(|r| r.mean_ns).collect()),
        })
    }
}

/// Delivery rate of the streaming phase (a window of messages in flight, see
/// [`crate::peer::stream_window`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Throughput {
    /// Messages delivered per second, from the first message's publish time to the last
    /// message's receive time.
    pub msgs_per_s: f64,
    /// `msgs_per_s` x message size, in 10^6 bytes per second.
    pub mb_per_s: f64,
    pub received: u64,
    /// Messages sent but never seen (overwritten in a full subscriber buffer); 0 while the
    /// window fits the buffer.
    pub dropped: u64,
}

impl Throughput {
    pub fn median_of(runs: &[Self]) -> Option<Self> {
        if runs.is_empty() {
            return None;
        }
        Some(Self {
            msgs_per_s: median_f64(runs.iter().map(|r| r.msgs_per_s).collect()),
            mb_per_s: median_f64(runs.iter().map(|r| r.mb_per_s).collect()),
            received: median_u64(runs.iter().map(|r| r.received).collect()),
            dropped: median_u64(runs.iter().map(|r| r.dropped).collect()),
        })
    }
}

/// Counts the streaming phase's messages as they arrive.
#[derive(Debug, Default, Clone, Copy)]
pub struct StreamTally {
    first: Option<(u64, u64)>,
    last_seq: u64,
    last_recv_ns: u64,
    received: u64,
}

impl StreamTally {
    /// One delivered message with its `msg_seq`, `publish_ns` and receive time.
    pub fn add(&mut self, msg_seq: u64, publish_ns: u64, recv_ns: u64) {
        self.first.get_or_insert((msg_seq, publish_ns));
        self.last_seq = msg_seq;
        self.last_recv_ns = recv_ns;
        self.received += 1;
    }

    pub fn throughput(&self, message_bytes: usize) -> Throughput {
        let Some((first_seq, first_publish_ns)) = self.first else {
            return Throughput {
                msgs_per_s: 0.0,
                mb_per_s: 0.0,
                received: 0,
                dropped: 0,
            };
        };
        let span_s = self.last_recv_ns.saturating_sub(first_publish_ns).max(1) as f64 * 1e-9;
        let msgs_per_s = self.received as f64 / span_s;
        let sent = self.last_seq.saturating_sub(first_seq) + 1;
        Throughput {
            msgs_per_s,
            mb_per_s: msgs_per_s * message_bytes as f64 / 1e6,
            received: self.received,
            dropped: sent.saturating_sub(self.received),
        }
    }
}

/// The `fraction` percentile of `values` (nearest rank: the value at `fraction` of the way
/// through the sorted values); sorts `values` in place; NaN when empty.
pub fn percentile(values: &mut [f64], fraction: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let index = ((values.len() - 1) as f64 * fraction).round() as usize;
    values[index.min(values.len() - 1)]
}

/// Median; the mean of the two middle values for an even count; 0 when empty.
pub fn median_f64(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

/// Median of integers (rounded down for an even count); 0 when empty.
pub fn median_u64(mut values: Vec<u64>) -> u64 {
    if values.is_empty() {
        return 0;
    }
    values.sort_unstable();
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        values[mid - 1] + (values[mid] - values[mid - 1]) / 2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_a_known_distribution() {
        let mut histogram = latency_histogram().expect("histogram");
        for value in 1..=1000u64 {
            histogram.record(value * 1000).expect("in range");
        }
        let summary = LatencySummary::from_histogram(&histogram);
        assert_eq!(summary.samples, 1000);
        // 3 significant digits: within 0.1 %.
        let near = |value: u64, expected: u64| value.abs_diff(expected) <= expected / 1000 + 1;
        assert!(near(summary.p50_ns, 500_000), "p50 {}", summary.p50_ns);
        assert!(near(summary.p90_ns, 900_000), "p90 {}", summary.p90_ns);
        assert!(near(summary.p99_ns, 990_000), "p99 {}", summary.p99_ns);
        assert!(near(summary.p999_ns, 999_000), "p99.9 {}", summary.p999_ns);
        assert!(near(summary.max_ns, 1_000_000), "max {}", summary.max_ns);
        assert!((summary.mean_ns - 500_500.0).abs() < 1000.0);
    }

    #[test]
    fn medians() {
        assert_eq!(median_u64(vec![5, 1, 3]), 3);
        assert_eq!(median_u64(vec![4, 1, 3, 10]), 3);
        assert_eq!(median_f64(vec![4.0, 1.0, 3.0, 10.0]), 3.5);
        assert_eq!(median_f64(Vec::new()), 0.0);
        let run = |p50_ns| LatencySummary {
            samples: 10,
            p50_ns,
            p90_ns: 2 * p50_ns,
            p99_ns: 3 * p50_ns,
            p999_ns: 4 * p50_ns,
            max_ns: 5 * p50_ns,
            mean_ns: p50_ns as f64,
        };
        let median = LatencySummary::median_of(&[run(30), run(10), run(20)]).expect("runs");
        assert_eq!(median, run(20));
        assert!(LatencySummary::median_of(&[]).is_none());
    }

    #[test]
    fn stream_tally_counts_gaps_and_rate() {
        let mut tally = StreamTally::default();
        // Messages 10..=19 published 1 ms apart; 12 and 13 were overwritten.
        for seq in (10..20u64).filter(|seq| *seq != 12 && *seq != 13) {
            let publish_ns = 1_000_000_000 + (seq - 10) * 1_000_000;
            tally.add(seq, publish_ns, publish_ns + 1_000);
        }
        let throughput = tally.throughput(1_000_000);
        assert_eq!(throughput.received, 8);
        assert_eq!(throughput.dropped, 2);
        // 8 messages over 9 ms + 1 us.
        let expected = 8.0 / 0.009001;
        assert!((throughput.msgs_per_s - expected).abs() < 1e-6 * expected);
        assert!((throughput.mb_per_s - expected).abs() < 1e-6 * expected);
    }
}
