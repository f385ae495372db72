//! Timing of a periodic control loop: the distribution of its tick-to-tick intervals.
//!
//! The arm and vacuum processes run at 200 Hz (a 5 ms control period, [dual-arm sec. 2.2]).
//! Each tick records the interval since the previous one; the percentiles tell how regular the
//! loop really is on the host (jitter = interval minus the nominal period). Recording does not
//! allocate: the histogram is sized once for intervals up to [`PeriodStats::MAX_RECORDED_NS`].

use hdrhistogram::Histogram;

/// Summary of the recorded intervals, ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct PeriodSummary {
    /// Intervals recorded.
    pub ticks: u64,
    /// Nominal period, ns.
    pub nominal_ns: u64,
    /// Median interval, ns.
    pub p50_ns: u64,
    /// 99th percentile interval, ns.
    pub p99_ns: u64,
    /// Longest interval, ns.
    pub max_ns: u64,
    /// Shortest interval, ns.
    pub min_ns: u64,
    /// Deadline misses: intervals longer than twice the nominal period, i.e. at least one tick
    /// slot passed without the loop running (on the loop's fixed tick schedule a tick that
    /// starts a whole period late has not finished before the next one was due).
    pub deadline_misses: u64,
}

impl PeriodSummary {
    /// `p99 - nominal`, ns (0 when the loop is early).
    pub fn p99_jitter_ns(&self) -> u64 {
        self.p99_ns.saturating_sub(self.nominal_ns)
    }
}

impl std::fmt::Display for PeriodSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let us = |ns: u64| ns as f64 * 1e-3;
        write!(
            f,
            "{} ticks, period {:.0} us nominal: p50 {:.0} us, p99 {:.0} us, max {:.0} us, min {:.0} \
             us, {} deadline miss(es) (> 2x)",
            self.ticks,
            us(self.nominal_ns),
            us(self.p50_ns),
            us(self.p99_ns),
            us(self.max_ns),
            us(self.min_ns),
            self.deadline_misses
        )
    }
}

/// Why [`PeriodStats`] could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PeriodStatsError {
    /// The nominal period is zero.
    #[error("control period must be > 0 ns")]
    ZeroPeriod,
    /// The histogram could not be created.
    #[error("period histogram: {0}")]
    Histogram(String),
}

/// Records tick-to-tick intervals of a loop with a nominal period.
#[derive(Debug, Clone)]
pub struct PeriodStats {
    nominal_ns: u64,
    last_tick_ns: Option<u64>,
    histogram: Histogram<u64>,
    deadline_misses: u64,
}

impl PeriodStats {
    /// Longest interval recorded exactly, ns (longer ones are clamped to it): 10 s.
    pub const MAX_RECORDED_NS: u64 = 10_000_000_000;

    /// Statistics of a loop of period `nominal_ns`.
    pub fn new(nominal_ns: u64) -> Result<Self, PeriodStatsError> {
        if nominal_ns == 0 {
            return Err(PeriodStatsError::ZeroPeriod);
        }
        // 3 significant digits: 1 us resolution around the 5 ms period.
        let histogram = Histogram::new_with_bounds(1, Self::MAX_RECORDED_NS, 3)
            .map_err(|error| PeriodStatsError::Histogram(error.to_string()))?;
        Ok(Self {
            nominal_ns,
            last_tick_ns: None,
            histogram,
            deadline_misses: 0,
        })
    }

    /// Records a tick at `now_ns`; returns the interval since the previous tick, ns.
    pub fn tick(&mut self, now_ns: u64) -> Option<u64> {
        let interval = self
            .last_tick_ns
            .map(|last| now_ns.saturating_sub(last).max(1));
        self.last_tick_ns = Some(now_ns);
        if let Some(interval) = interval {
            self.histogram.saturating_record(interval);
            if interval > 2 * self.nominal_ns {
                self.deadline_misses += 1;
            }
        }
        interval
    }

    /// The distribution so far.
    pub fn summary(&self) -> PeriodSummary {
        if self.histogram.is_empty() {
            return PeriodSummary {
                nominal_ns: self.nominal_ns,
                ..PeriodSummary::default()
            };
        }
        PeriodSummary {
            ticks: self.histogram.len(),
            nominal_ns: self.nominal_ns,
            p50_ns: self.histogram.value_at_quantile(0.5),
            p99_ns: self.histogram.value_at_quantile(0.99),
            max_ns: self.histogram.max(),
            min_ns: self.histogram.min(),
            deadline_misses: self.deadline_misses,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_a_known_sequence() {
        let mut stats = PeriodStats::new(5_000_000).expect("stats");
        let mut t = 1_000_000_000u64;
        stats.tick(t);
        // 98 regular ticks, one 6 ms and one 20 ms tick.
        for _ in 0..98 {
            t += 5_000_000;
            assert_eq!(stats.tick(t), Some(5_000_000));
        }
        t += 6_000_000;
        stats.tick(t);
        t += 20_000_000;
        stats.tick(t);
        let s = stats.summary();
        assert_eq!(s.ticks, 100);
        let close = |a: u64, b: u64| a.abs_diff(b) <= b / 500;
        assert!(close(s.p50_ns, 5_000_000), "{s:?}");
        assert!(close(s.p99_ns, 6_000_000), "{s:?}");
        assert!(close(s.max_ns, 20_000_000), "{s:?}");
        assert!(close(s.min_ns, 5_000_000), "{s:?}");
        assert_eq!(s.deadline_misses, 1);
        assert!(close(s.p99_jitter_ns(), 1_000_000), "{s:?}");
    }

    #[test]
    fn empty_and_invalid() {
        assert_eq!(
            PeriodStats::new(0).err(),
            Some(PeriodStatsError::ZeroPeriod)
        );
        let stats = PeriodStats::new(5_000_000).expect("stats");
        assert_eq!(stats.summary().ticks, 0);
    }
}
