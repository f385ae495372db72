//! Wall-clock time, which only appears in recording metadata and file names: one
//! (monotonic, realtime) pair per recording lets readers convert the stack-clock stamps
//! (`CLOCK_MONOTONIC` ns, see `harvest_ipc::clock`) to UTC:
//! `realtime_ns = monotonic_ns + (pair.realtime_ns - pair.monotonic_ns)`.

use harvest_ipc::MonotonicClock;
use std::time::{SystemTime, UNIX_EPOCH};

/// One simultaneous reading of the stack clock and of the realtime clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockPair {
    pub monotonic_ns: u64,
    /// Nanoseconds since the Unix epoch, UTC.
    pub realtime_ns: u64,
}

impl ClockPair {
    /// Reads both clocks; the monotonic value is the midpoint of two readings around the
    /// realtime reading, so the pair's error is half the (sub-microsecond) read interval.
    pub fn now() -> Self {
        let before_ns = MonotonicClock::read_ns();
        let realtime_ns = realtime_now_ns();
        let after_ns = MonotonicClock::read_ns();
        Self {
            monotonic_ns: before_ns + (after_ns - before_ns) / 2,
            realtime_ns,
        }
    }

    /// Offset to add to a monotonic stamp to get realtime, in ns (may be negative).
    pub fn realtime_offset_ns(&self) -> i128 {
        self.realtime_ns as i128 - self.monotonic_ns as i128
    }

    /// Converts a stack-clock stamp to realtime ns (0 when it would precede the epoch).
    pub fn to_realtime_ns(&self, monotonic_ns: u64) -> u64 {
        let realtime = monotonic_ns as i128 + self.realtime_offset_ns();
        realtime.clamp(0, u64::MAX as i128) as u64
    }
}

/// Realtime clock, ns since the Unix epoch (0 if the clock is before 1970).
pub fn realtime_now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|elapsed| elapsed.as_nanos().min(u64::MAX as u128) as u64)
        .unwrap_or(0)
}

/// UTC calendar fields of a Unix time: (year, month 1-12, day 1-31, hour, minute, second).
pub fn utc_fields(unix_s: u64) -> (i64, u32, u32, u32, u32, u32) {
    let days = (unix_s / 86_400) as i64;
    let seconds_of_day = unix_s % 86_400;
    // Civil-from-days (proleptic Gregorian), after H. Hinnant's public-domain algorithm.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let day_of_era = z.rem_euclid(146_097);
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_index = (5 * day_of_year + 2) / 153;
    let day = (day_of_year - (153 * month_index + 2) / 5 + 1) as u32;
    let month = if month_index < 10 {
        month_index + 3
    } else {
        month_index - 9
    } as u32;
    let year = year_of_era + era * 400 + i64::from(month <= 2);
    (
        year,
        month,
        day,
        (seconds_of_day / 3600) as u32,
        (seconds_of_day / 60 % 60) as u32,
        (seconds_of_day % 60) as u32,
    )
}

/// `2025-03-01T12:34:56.789Z` for a realtime stamp in ns.
pub fn format_utc_iso(realtime_ns: u64) -> String {
    let (year, month, day, hour, minute, second) = utc_fields(realtime_ns / 1_000_000_000);
    let millis = realtime_ns / 1_000_000 % 1000;
    format!("{year:04}-{month:02}-{day:02}T{hour:02}:{minute:02}:{second:02}.{millis:03}Z")
}

/// `20250301T123456Z` for file names.
pub fn format_utc_compact(realtime_ns: u64) -> String {
    let (year, month, day, hour, minute, second) = utc_fields(realtime_ns / 1_000_000_000);
    format!("{year:04}{month:02}{day:02}T{hour:02}{minute:02}{second:02}Z")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(utc_fields(0), (1970, 1, 1, 0, 0, 0));
        // 2000-02-29 12:00:00 UTC (leap day) = 951825600.
        assert_eq!(utc_fields(951_825_600), (2000, 2, 29, 12, 0, 0));
        // 2024-12-31 23:59:59 UTC = 1735689599.
        assert_eq!(utc_fields(1_735_689_599), (2024, 12, 31, 23, 59, 59));
        assert_eq!(
            format_utc_iso(1_735_689_599_123_000_000),
            "2024-12-31T23:59:59.123Z"
        );
        assert_eq!(
            format_utc_compact(951_825_600_000_000_000),
            "20000229T120000Z"
        );
    }

    #[test]
    fn clock_pair_converts_monotonic_stamps() {
        let pair = ClockPair {
            monotonic_ns: 1_000,
            realtime_ns: 1_000_000,
        };
        assert_eq!(pair.to_realtime_ns(1_500), 1_000_500);
        let now = ClockPair::now();
        assert!(now.realtime_ns > 1_600_000_000_000_000_000);
        assert_eq!(now.to_realtime_ns(now.monotonic_ns), now.realtime_ns);
    }
}
