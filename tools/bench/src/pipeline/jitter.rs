//! Period jitter of a 200 Hz control loop (an arm, the vacuum supervisor) from consecutive
//! publish stamps of one channel.
//!
//! The arm process runs its control loop at 200 Hz ([dual-arm sec. 2.2]: 5 ms control period) and
//! publishes `armN/command` and `armN/state` once per cycle. The period of cycle k is
//! `publish_ns[k] - publish_ns[k-1]` for consecutive `msg_seq` (a gap, i.e. a message the bench
//! did not see, breaks the pair); its deviation is `|period - 5 ms|`.

use crate::pipeline::summary::{Samples, Summary};
use harvest_ipc::Header;
use serde::Serialize;

/// The arm control loop's nominal period: 200 Hz.
pub const NOMINAL_CONTROL_PERIOD_NS: u64 = 5_000_000;

/// Collects the periods of one channel.
#[derive(Debug, Default)]
pub struct PeriodTracker {
    last: Option<(u64, u64)>,
    periods: Samples,
    deviations: Samples,
    /// Pairs broken by a `msg_seq` gap.
    gaps: u64,
}

/// The jitter of one channel's publish period.
#[derive(Debug, Clone, Serialize)]
pub struct JitterResult {
    pub channel: String,
    pub nominal_period_ns: u64,
    /// Consecutive pairs measured.
    pub periods: u64,
    /// Pairs broken by a `msg_seq` gap (messages the bench missed).
    pub gaps: u64,
    /// The measured period's distribution (None: no data).
    pub period: Option<Summary>,
    /// `|period - nominal|` (None: no data).
    pub deviation: Option<Summary>,
}

impl PeriodTracker {
    /// One message of the channel; `recording` false only remembers it.
    pub fn on_message(&mut self, header: &Header, recording: bool) {
        if let Some((last_seq, last_publish_ns)) = self.last
            && recording
        {
            if header.msg_seq == last_seq + 1 && header.publish_ns >= last_publish_ns {
                let period_ns = header.publish_ns - last_publish_ns;
                self.periods.push(period_ns);
                self.deviations
                    .push(period_ns.abs_diff(NOMINAL_CONTROL_PERIOD_NS));
            } else {
                self.gaps += 1;
            }
        }
        self.last = Some((header.msg_seq, header.publish_ns));
    }

    pub fn result(&self, channel: &str) -> JitterResult {
        JitterResult {
            channel: channel.to_owned(),
            nominal_period_ns: NOMINAL_CONTROL_PERIOD_NS,
            periods: self.periods.len() as u64,
            gaps: self.gaps,
            period: self.periods.summary(),
            deviation: self.deviations.summary(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(msg_seq: u64, publish_ns: u64) -> Header {
        Header {
            msg_seq,
            capture_ns: 0,
            publish_ns,
        }
    }

    #[test]
    fn deviations_from_known_periods_and_gaps() {
        let mut tracker = PeriodTracker::default();
        tracker.on_message(&header(1, 0), false);
        // Periods 5.0, 5.2, 4.9 ms, then a gap (seq 5 missing), then 5.1 ms.
        let stamps = [
            (2, 5_000_000),
            (3, 10_200_000),
            (4, 15_100_000),
            (6, 25_000_000),
            (7, 30_100_000),
        ];
        for (seq, ns) in stamps {
            tracker.on_message(&header(seq, ns), true);
        }
        let result = tracker.result("arm1/command");
        assert_eq!(result.periods, 4);
        assert_eq!(result.gaps, 1);
        let deviation = result.deviation.expect("deviations");
        // Deviations 0, 200, 100, 100 us: nearest-rank median 100 us, max 200 us.
        assert_eq!(deviation.p50_ns, 100_000);
        assert_eq!(deviation.max_ns, 200_000);
        assert_eq!(result.period.expect("periods").p50_ns, 5_000_000);
    }

    #[test]
    fn no_messages_is_no_data() {
        let result = PeriodTracker::default().result("arm2/state");
        assert_eq!(result.periods, 0);
        assert!(result.deviation.is_none() && result.period.is_none());
    }
}
