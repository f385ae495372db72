//! The device's status word (`LidarErrorCode` in `livox_def.h`), carried in every point packet
//! and every heartbeat acknowledgement. Bit fields, least significant first:
//!
//! | bits | field | values |
//! |---|---|---|
//! | 0-1 | temperature | 0 normal, 1 high or low, 2 extremely high or low |
//! | 2-3 | voltage | 0 normal, 1 high, 2 extremely high |
//! | 4-5 | motor | 0 normal, 1 warning, 2 error (unable to work) |
//! | 6-7 | window dirty or blocked | 0 no, 1 yes |
//! | 8 | firmware abnormal | |
//! | 9 | PPS signal present | |
//! | 10 | approaching end of service life | |
//! | 11 | fan warning | |
//! | 12 | low-temperature self heating on | |
//! | 13 | PTP signal present | |
//! | 14-16 | time sync | 0 none, 1 PTP, 2 GPS, 3 PPS, 4 abnormal |
//! | 30-31 | system | 0 normal, 1 warning, 2 error |

/// Overall state the device reports (bits 30-31).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Measuring normally.
    Normal,
    /// Measuring, with a warning bit set.
    Warning,
    /// An error bit set: the device cannot measure properly.
    Error,
}

/// The decoded status word.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StatusCode(pub u32);

impl StatusCode {
    fn field(self, shift: u32, width: u32) -> u32 {
        (self.0 >> shift) & ((1 << width) - 1)
    }

    /// The device's own summary (bits 30-31; 3 is taken as an error).
    pub fn severity(self) -> Severity {
        match self.field(30, 2) {
            0 => Severity::Normal,
            1 => Severity::Warning,
            _ => Severity::Error,
        }
    }

    /// Time synchronisation in use (bits 14-16): 0 none, 1 PTP, 2 GPS, 3 PPS, 4 abnormal.
    pub fn time_sync(self) -> u32 {
        self.field(14, 3)
    }

    /// True when the highest-priority sync signal was lost (time sync state 4).
    pub fn time_sync_abnormal(self) -> bool {
        self.time_sync() == 4
    }

    /// The conditions the word flags, as short names for logs and health (empty when normal).
    pub fn conditions(self) -> impl Iterator<Item = &'static str> {
        let flags = [
            (self.field(0, 2) == 1, "temperature_high_or_low"),
            (self.field(0, 2) >= 2, "temperature_extreme"),
            (self.field(2, 2) == 1, "voltage_high"),
            (self.field(2, 2) >= 2, "voltage_extreme"),
            (self.field(4, 2) == 1, "motor_warning"),
            (self.field(4, 2) >= 2, "motor_error"),
            (self.field(6, 2) != 0, "window_dirty_or_blocked"),
            (self.field(8, 1) != 0, "firmware_abnormal"),
            (self.field(10, 1) != 0, "end_of_service_life"),
            (self.field(11, 1) != 0, "fan_warning"),
            (self.time_sync_abnormal(), "time_sync_abnormal"),
        ];
        flags
            .into_iter()
            .filter_map(|(active, name)| active.then_some(name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_decode_at_their_bits() {
        assert_eq!(StatusCode(0).severity(), Severity::Normal);
        assert_eq!(StatusCode(0).conditions().count(), 0);
        let motor_error_system_error = (2 << 4) | (2 << 30);
        let status = StatusCode(motor_error_system_error);
        assert_eq!(status.severity(), Severity::Error);
        assert_eq!(status.conditions().collect::<Vec<_>>(), ["motor_error"]);
        let dirty_warning_ptp = (1 << 6) | (1 << 13) | (1 << 14) | (1 << 30);
        let status = StatusCode(dirty_warning_ptp);
        assert_eq!(status.severity(), Severity::Warning);
        assert_eq!(status.time_sync(), 1);
        assert_eq!(
            status.conditions().collect::<Vec<_>>(),
            ["window_dirty_or_blocked"]
        );
        assert!(StatusCode(4 << 14).time_sync_abnormal());
    }
}
