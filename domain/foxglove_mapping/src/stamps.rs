//! Which clock mapped messages carry.
//!
//! Stack stamps are `CLOCK_MONOTONIC` nanoseconds (`harvest_ipc::clock`). A mapped message's
//! `timestamp` fields and its log time are on one output time base: the monotonic clock itself
//! inside a recording (so the mapped channels share the raw channels' timeline), wall-clock UTC
//! live and in exports (monotonic + the offset of a clock pair read at one instant).

use foxglove::messages::Timestamp;

/// Converts stack stamps (monotonic ns) to the output time base.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TimeBase {
    /// Added to a monotonic stamp, ns (0: stay on the monotonic clock).
    offset_ns: i64,
}

impl TimeBase {
    /// Stamps stay monotonic nanoseconds (recordings).
    pub const MONOTONIC: Self = Self { offset_ns: 0 };

    /// Stamps become wall-clock nanoseconds since the Unix epoch, given one pair of readings of
    /// both clocks taken at the same instant.
    pub fn realtime(monotonic_ns: u64, realtime_ns: u64) -> Self {
        let offset = i128::from(realtime_ns) - i128::from(monotonic_ns);
        Self {
            offset_ns: i64::try_from(offset).unwrap_or(0),
        }
    }

    /// `monotonic_ns` on the output time base (saturating at 0 and `u64::MAX`).
    pub fn ns(&self, monotonic_ns: u64) -> u64 {
        let shifted = i128::from(monotonic_ns) + i128::from(self.offset_ns);
        u64::try_from(shifted.max(0)).unwrap_or(u64::MAX)
    }

    /// `monotonic_ns` on the output time base as a protobuf timestamp.
    pub fn timestamp(&self, monotonic_ns: u64) -> Timestamp {
        timestamp_of_ns(self.ns(monotonic_ns))
    }
}

/// Nanoseconds as a protobuf timestamp (seconds saturate at `u32::MAX`, the year 2106).
pub fn timestamp_of_ns(ns: u64) -> Timestamp {
    let sec = u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new_checked(sec, (ns % 1_000_000_000) as u32).unwrap_or(Timestamp::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_bases_shift_and_split_stamps() {
        assert_eq!(TimeBase::MONOTONIC.ns(42), 42);
        let realtime = TimeBase::realtime(1_000, 1_700_000_000_000_000_000);
        assert_eq!(realtime.ns(3_000), 1_700_000_000_000_002_000);
        let stamp = realtime.timestamp(1_500_000_500);
        assert_eq!(stamp.sec(), 1_700_000_001);
        assert_eq!(stamp.nsec(), 499_999_500);
        // A stamp before the pair's monotonic reading stays on the base.
        assert_eq!(TimeBase::realtime(5_000, 1_000).ns(10), 0);
    }
}
