//! How a recording's log and publish times read: on the stack clock (`CLOCK_MONOTONIC` ns) or
//! as wall-clock time.
//!
//! The recorder writes log and publish times in Unix-epoch nanoseconds, UTC: the stack-clock
//! stamp plus one offset read at the session's start (`log_time_offset_ns` in the
//! `harvest.clock` record), so Foxglove's timeline shows the date and files of one day line
//! up. The payloads keep their stack-clock stamps. Files written before that carry stack-clock
//! log times and no offset: readers see offset 0 and convert to UTC with the clock pair.
//! Readers that compare log times with payload stamps (the monitor) or map them again (the
//! Foxglove export) go through [`FileTimeBase::stack_ns`]; readers that only take differences
//! (replay, windows, rates) need nothing.

use crate::metadata;
use crate::wall_clock::ClockPair;
use mcap::records::Metadata;

/// The time base of one recording, learnt from its `harvest.clock` record.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FileTimeBase {
    /// The first clock pair of the file, when it has one.
    pub clock: Option<ClockPair>,
    /// `log_time = stack_ns + log_time_offset_ns`; `None` in files with stack-clock log times.
    pub log_time_offset_ns: Option<i64>,
}

impl FileTimeBase {
    /// Takes in a metadata record; the first `harvest.clock` record decides.
    pub fn observe(&mut self, record: &Metadata) {
        if self.clock.is_some() {
            return;
        }
        if let Some(pair) = metadata::parse_clock(record) {
            self.clock = Some(pair);
            self.log_time_offset_ns = metadata::parse_log_time_offset(record);
        }
    }

    /// True when the file's log times are wall-clock time.
    pub fn is_wall_clock(&self) -> bool {
        self.log_time_offset_ns.is_some()
    }

    /// A file log or publish time as a stack-clock stamp (monotonic ns of the recording host).
    pub fn stack_ns(&self, log_time: u64) -> u64 {
        let offset = i128::from(self.log_time_offset_ns.unwrap_or(0));
        (i128::from(log_time) - offset).clamp(0, i128::from(u64::MAX)) as u64
    }

    /// A file log time as Unix-epoch ns, UTC (`None` for an old file without a clock record).
    pub fn realtime_ns(&self, log_time: u64) -> Option<u64> {
        if self.is_wall_clock() {
            return Some(log_time);
        }
        self.clock.map(|pair| pair.to_realtime_ns(log_time))
    }

    /// The pair that converts this file's stack-clock stamps to UTC the way its log times were
    /// converted (the session offset when the file has one, else its clock pair).
    pub fn realtime_pair(&self) -> Option<ClockPair> {
        match (self.log_time_offset_ns, self.clock) {
            (Some(offset), Some(pair)) => Some(ClockPair {
                monotonic_ns: pair.monotonic_ns,
                realtime_ns: (i128::from(pair.monotonic_ns) + i128::from(offset))
                    .clamp(0, i128::from(u64::MAX)) as u64,
            }),
            (None, clock) => clock,
            (Some(_), None) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wall_clock_files_convert_back_to_the_stack_clock() {
        let pair = ClockPair {
            monotonic_ns: 5_000,
            realtime_ns: 1_700_000_000_000_005_000,
        };
        let offset = 1_700_000_000_000_000_000;
        let mut base = FileTimeBase::default();
        base.observe(&metadata::record(metadata::NOTES, [("a", "b")]));
        assert_eq!(base, FileTimeBase::default());
        base.observe(&metadata::clock_record(pair, Some(offset)));
        assert!(base.is_wall_clock());
        assert_eq!(base.stack_ns(offset as u64 + 42), 42);
        assert_eq!(
            base.realtime_ns(offset as u64 + 42),
            Some(offset as u64 + 42)
        );
        assert_eq!(
            base.realtime_pair().map(|p| p.to_realtime_ns(42)),
            Some(offset as u64 + 42)
        );
        // A second clock record (a later segment) does not change the base.
        base.observe(&metadata::clock_record(pair, Some(7)));
        assert_eq!(base.log_time_offset_ns, Some(offset));
    }

    #[test]
    fn old_files_keep_stack_clock_log_times() {
        let pair = ClockPair {
            monotonic_ns: 1_000,
            realtime_ns: 1_000_000,
        };
        let mut base = FileTimeBase::default();
        base.observe(&metadata::clock_record(pair, None));
        assert!(!base.is_wall_clock());
        assert_eq!(base.stack_ns(1_500), 1_500);
        assert_eq!(base.realtime_ns(1_500), Some(1_000_500));
        assert_eq!(FileTimeBase::default().realtime_ns(3), None);
    }
}
