//! Pacing of what leaves the robot. [`RateGate`]: at most one message per period, and the
//! newest one (a value offered while the gate is shut replaces the one waiting; the caller
//! sends the waiting one when the gate opens). [`ChangeBeat`]: a message when the value
//! changes, and the unchanged value again after a slow beat so a station that joined late, or
//! lost messages, sees the state within one beat.

/// At most one message per `period_ns`, latest only.
#[derive(Debug, Clone)]
pub struct RateGate<T> {
    period_ns: u64,
    last_sent_ns: Option<u64>,
    waiting: Option<T>,
    /// Values replaced before they could be sent.
    superseded: u64,
}

impl<T> RateGate<T> {
    /// A gate of `max_hz` messages per second (`max_hz` > 0).
    pub fn with_max_hz(max_hz: f64) -> Self {
        let period_ns = if max_hz > 0.0 && max_hz.is_finite() {
            (1e9 / max_hz) as u64
        } else {
            u64::MAX
        };
        Self {
            period_ns,
            last_sent_ns: None,
            waiting: None,
            superseded: 0,
        }
    }

    /// Offers the newest value; it replaces any value waiting.
    pub fn offer(&mut self, value: T) {
        if self.waiting.replace(value).is_some() {
            self.superseded += 1;
        }
    }

    /// Whether a message may go at `now_ns`.
    pub fn open(&self, now_ns: u64) -> bool {
        self.last_sent_ns
            .is_none_or(|last| now_ns.saturating_sub(last) >= self.period_ns)
    }

    /// The value to send now, if one waits and the gate is open (the send is noted).
    pub fn take_due(&mut self, now_ns: u64) -> Option<T> {
        if self.waiting.is_some() && self.open(now_ns) {
            self.last_sent_ns = Some(now_ns);
            return self.waiting.take();
        }
        None
    }

    /// Values replaced before they could be sent (by design: latest only).
    pub fn superseded(&self) -> u64 {
        self.superseded
    }

    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }
}

/// On change, plus the unchanged value every `beat_ns`.
#[derive(Debug, Clone)]
pub struct ChangeBeat<T> {
    beat_ns: u64,
    last: Option<(T, u64)>,
}

impl<T: PartialEq + Clone> ChangeBeat<T> {
    pub fn new(beat_ns: u64) -> Self {
        Self {
            beat_ns,
            last: None,
        }
    }

    /// Whether `value` goes out at `now_ns`: it differs from the last sent, or the beat is due.
    pub fn due(&mut self, value: &T, now_ns: u64) -> bool {
        let send = match &self.last {
            None => true,
            Some((last, sent_ns)) => {
                last != value || now_ns.saturating_sub(*sent_ns) >= self.beat_ns
            }
        };
        if send {
            self.last = Some((value.clone(), now_ns));
        }
        send
    }

    /// The last value sent, when its beat is due at `now_ns` (the value did not change).
    pub fn beat_due(&mut self, now_ns: u64) -> Option<T> {
        let (value, sent_ns) = self.last.as_mut()?;
        if now_ns.saturating_sub(*sent_ns) >= self.beat_ns {
            *sent_ns = now_ns;
            return Some(value.clone());
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn the_gate_sends_the_newest_at_most_once_per_period() {
        let mut gate = RateGate::with_max_hz(20.0);
        assert_eq!(gate.period_ns(), 50 * MS);
        gate.offer(1);
        assert_eq!(gate.take_due(0), Some(1));
        gate.offer(2);
        gate.offer(3);
        assert_eq!(gate.take_due(10 * MS), None);
        assert_eq!(gate.take_due(50 * MS), Some(3));
        assert_eq!(gate.superseded(), 1);
        assert_eq!(gate.take_due(200 * MS), None, "nothing waits");
        // 200 Hz offered for one second: 20 sent.
        let mut gate = RateGate::with_max_hz(20.0);
        let sent = (0..200u64)
            .filter(|i| {
                gate.offer(*i);
                gate.take_due(i * 5 * MS).is_some()
            })
            .count();
        assert_eq!(sent, 20);
    }

    #[test]
    fn changes_go_at_once_and_the_beat_repeats() {
        let mut beat = ChangeBeat::new(1000 * MS);
        assert!(beat.due(&"idle", 0));
        assert!(!beat.due(&"idle", 10 * MS));
        assert!(beat.due(&"harvesting", 20 * MS));
        assert_eq!(beat.beat_due(500 * MS), None);
        assert_eq!(beat.beat_due(1020 * MS), Some("harvesting"));
        assert!(!beat.due(&"harvesting", 1030 * MS));
        assert!(beat.due(&"harvesting", 2100 * MS));
    }
}
