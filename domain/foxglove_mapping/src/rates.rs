//! The viewing rates: how often each stack channel is mapped for viewing (the live bridge and
//! the recorder's mapped channels). Exports map every message.

use harvest_ipc::catalogue;
use std::time::Duration;

/// Per-channel rate limits for viewing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewingRates {
    /// `camera/rgbd` -> `/camera/image` (the costly one: a JPEG per image), Hz.
    pub camera_hz: f64,
    /// `armN/state` and `vacuum/state` (200 Hz in the stack), Hz.
    pub state_hz: f64,
}

impl Default for ViewingRates {
    fn default() -> Self {
        Self::VIEWING
    }
}

impl ViewingRates {
    /// Camera 10 Hz, arm and vacuum states 20 Hz; every other channel at its own rate (they
    /// are 10 Hz or less, or events).
    pub const VIEWING: Self = Self {
        camera_hz: 10.0,
        state_hz: 20.0,
    };

    /// The least time between two mapped messages of the stack channel `topic` (`None`: every
    /// message is mapped).
    pub fn min_interval(&self, topic: &str) -> Option<Duration> {
        let hz = if topic == catalogue::CAMERA_RGBD.spec.topic {
            self.camera_hz
        } else if topic == catalogue::VACUUM_STATE.spec.topic
            || catalogue::ARM_STATE
                .iter()
                .any(|channel| channel.spec.topic == topic)
        {
            self.state_hz
        } else {
            return None;
        };
        (hz > 0.0 && hz.is_finite()).then(|| Duration::from_secs_f64(1.0 / hz))
    }

    /// The problem with these rates, if any.
    pub fn problem(&self) -> Option<String> {
        for (name, hz) in [("camera", self.camera_hz), ("state", self.state_hz)] {
            if !(hz > 0.0 && hz <= 1000.0) {
                return Some(format!("{name} rate {hz} Hz is not in (0, 1000]"));
            }
        }
        None
    }
}

/// Lets one message through per interval (by the stamps it is shown, not by sleeping).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RateLimit {
    interval_ns: u64,
    next_ns: Option<u64>,
}

impl RateLimit {
    /// `None`: no limit.
    pub fn new(min_interval: Option<Duration>) -> Self {
        Self {
            interval_ns: min_interval.map_or(0, |interval| {
                u64::try_from(interval.as_nanos()).unwrap_or(u64::MAX)
            }),
            next_ns: None,
        }
    }

    /// True when a message at `now_ns` is due. The schedule advances by whole intervals, so the
    /// long-run rate never exceeds the configured one; a message up to a fifth of an interval
    /// early still counts as on time, so a source at about the limit's rate (with jitter) is not
    /// halved. After a gap the schedule restarts from `now_ns`.
    pub fn admit(&mut self, now_ns: u64) -> bool {
        if self.interval_ns == 0 {
            return true;
        }
        let tolerance_ns = self.interval_ns / 5;
        match self.next_ns {
            Some(next) if now_ns.saturating_add(tolerance_ns) < next => false,
            Some(next) => {
                let advanced = next.saturating_add(self.interval_ns);
                self.next_ns = Some(if advanced <= now_ns {
                    now_ns.saturating_add(self.interval_ns)
                } else {
                    advanced
                });
                true
            }
            None => {
                self.next_ns = Some(now_ns.saturating_add(self.interval_ns));
                true
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thirty_hz_frames_become_ten_hz() {
        let rates = ViewingRates::VIEWING;
        let mut limit = RateLimit::new(rates.min_interval("camera/rgbd"));
        let period_ns = 1_000_000_000 / 30;
        let admitted = (0..300u64)
            .filter(|frame| limit.admit(frame * period_ns + 1_000))
            .count();
        assert_eq!(admitted, 100);
        assert_eq!(rates.min_interval("harvest/events"), None);
        assert_eq!(
            rates.min_interval("arm2/state"),
            Some(Duration::from_millis(50))
        );
        // A source at the limit's own rate with +-8 ms of jitter keeps its rate.
        let mut limit = RateLimit::new(rates.min_interval("camera/rgbd"));
        let jittery = (0..100u64)
            .filter(|frame| {
                let jitter_ns = if frame % 2 == 0 { 8_000_000 } else { 0 };
                limit.admit(1_000_000_000 + frame * 100_000_000 - jitter_ns)
            })
            .count();
        assert_eq!(jittery, 100);
        let mut unlimited = RateLimit::new(None);
        assert!((0..10).all(|_| unlimited.admit(5)));
        assert!(
            ViewingRates {
                camera_hz: 0.0,
                state_hz: 20.0
            }
            .problem()
            .is_some()
        );
    }
}
