//! A token bucket: bursts up to `capacity`, then `refill_per_s` a second.

/// See the module docs.
#[derive(Debug, Clone)]
pub struct TokenBucket {
    capacity: f64,
    refill_per_ns: f64,
    tokens: f64,
    last_ns: Option<u64>,
}

impl TokenBucket {
    /// A full bucket.
    pub fn new(capacity: u32, refill_per_s: f64) -> Self {
        Self {
            capacity: f64::from(capacity),
            refill_per_ns: refill_per_s.max(0.0) * 1e-9,
            tokens: f64::from(capacity),
            last_ns: None,
        }
    }

    /// Takes one token at `now_ns`; false when the bucket is empty.
    pub fn take(&mut self, now_ns: u64) -> bool {
        if let Some(last) = self.last_ns {
            let elapsed = now_ns.saturating_sub(last) as f64;
            self.tokens = (self.tokens + elapsed * self.refill_per_ns).min(self.capacity);
        }
        self.last_ns = Some(now_ns);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_burst_then_the_refill_rate() {
        let mut bucket = TokenBucket::new(5, 10.0);
        assert_eq!((0..10).filter(|_| bucket.take(0)).count(), 5);
        assert!(!bucket.take(50_000_000));
        assert!(bucket.take(100_000_000));
        // A long pause refills to the capacity only.
        assert_eq!((0..10).filter(|_| bucket.take(10_000_000_000)).count(), 5);
    }
}
