//! Device time -> the stack's clock (`CLOCK_MONOTONIC` nanoseconds, `harvest_ipc::clock`), for
//! devices that stamp their data with a clock of their own (the Livox Mid-70's point packets, a
//! GigE Vision camera's frames).
//!
//! Each datum gives one sample of `offset = host_receive_ns - device_ns`: the true clock offset
//! plus a delay that is never negative. The estimate is the running minimum of the samples (the
//! data that crossed the link fastest), allowed to rise by [`DRIFT_ALLOWANCE_PPM`] of the host
//! time elapsed so that it follows a device clock running slower than the host's; a device
//! clock running faster pulls the minimum down by itself. A stamp is then `device_ns + offset`:
//! device-accurate spacing, and an absolute error of the smallest transport delay seen.
//!
//! Livox Mid-70: every point packet carries the device time of its first firing; the firings
//! are 10 us apart, so the sample pairs the packet's last firing (`first + (n - 1) * 10 us`)
//! with the datagram's arrival; the error is tens of microseconds on a direct link. GigE
//! Vision: the frame's timestamp (the camera's tick counter, in ns) pairs with the host time the
//! frame's first packet arrived; the error is the camera's shortest readout-to-leader delay.
//!
//! The same estimator serves every synchronisation, because the stack's clock is never the
//! device's epoch: without synchronisation (Livox type 0, a free-running camera) the device
//! counts from its power-up on its own oscillator (tens of ppm off the host's, tracked by the
//! minimum filter); with PTP, PPS or GPS the device counts the master's time, the offset is
//! nearly constant and the estimate settles. What synchronisation adds is agreement between
//! several devices disciplined by the same master, not a different mapping here.
//!
//! The estimate starts over ([`ClockMapping::resets`]) when the device's time runs backwards
//! (a reboot, a PTP step back), jumps forwards by more than [`MAX_FORWARD_JUMP_NS`] beyond the
//! host's elapsed time (a step, PPS realignment), or after [`MAX_SILENCE_NS`] without data.

/// How fast the estimated offset may rise without a sample pinning it, parts per million of
/// elapsed host time (above any oscillator's error; the error it adds between two fast packets
/// is 0.2 us per millisecond).
pub const DRIFT_ALLOWANCE_PPM: u64 = 200;
/// A forward jump of the device time beyond the host's elapsed time by more than this restarts
/// the estimate.
pub const MAX_FORWARD_JUMP_NS: i64 = 50_000_000;
/// Samples further apart than this in host time restart the estimate.
pub const MAX_SILENCE_NS: u64 = 1_000_000_000;

/// The running device -> host clock offset.
#[derive(Debug, Clone, Default)]
pub struct ClockMapping {
    /// `host - device`, nanoseconds.
    offset_ns: Option<i128>,
    last_host_ns: u64,
    last_device_ns: u64,
    resets: u64,
}

impl ClockMapping {
    /// A mapping that has seen no timestamp yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one sample (`device_ns`: the datum's device time, e.g. a packet's last firing;
    /// `host_ns`: when the host received it) and returns the current offset, host minus device, nanoseconds.
    pub fn observe(&mut self, device_ns: u64, host_ns: u64) -> i128 {
        let sample = i128::from(host_ns) - i128::from(device_ns);
        let estimate = match self.offset_ns {
            None => sample,
            Some(previous) => {
                let host_elapsed = host_ns.saturating_sub(self.last_host_ns);
                let device_elapsed = i128::from(device_ns) - i128::from(self.last_device_ns);
                let backwards = device_elapsed < 0;
                let jumped =
                    device_elapsed - i128::from(host_elapsed) > i128::from(MAX_FORWARD_JUMP_NS);
                if backwards || jumped || host_elapsed > MAX_SILENCE_NS {
                    self.resets += 1;
                    sample
                } else {
                    let leak = i128::from(host_elapsed * DRIFT_ALLOWANCE_PPM / 1_000_000);
                    (previous + leak).min(sample)
                }
            }
        };
        self.offset_ns = Some(estimate);
        self.last_host_ns = host_ns;
        self.last_device_ns = device_ns;
        estimate
    }

    /// The stack-clock time of a device time, with the current offset (None before the first
    /// sample or when the result would be negative).
    pub fn to_host_ns(&self, device_ns: u64) -> Option<u64> {
        let host = i128::from(device_ns) + self.offset_ns?;
        u64::try_from(host).ok()
    }

    /// When the newest sample arrived, stack clock (0 before the first): no datum taken so far
    /// can be stamped later than this.
    pub fn last_host_ns(&self) -> u64 {
        self.last_host_ns
    }

    /// Times the estimate started over (the first sample not counted).
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// Forgets the estimate (a new session with the device).
    pub fn clear(&mut self) {
        self.offset_ns = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_minimum_delay_is_found_and_drift_followed() {
        let mut mapping = ClockMapping::new();
        let true_offset: i128 = 5_000_000_000;
        // Device 30 ppm slow: its time advances 0.99997 ns per host ns. Delays 50-550 us, the
        // fastest every tenth packet.
        for k in 0..20_000u64 {
            let host_event = 10_000_000_000 + k * 960_000;
            let device = ((host_event as i128 - true_offset) as f64 * (1.0 - 30e-6)) as u64;
            let delay = if k % 10 == 0 {
                50_000
            } else {
                50_000 + (k * 7919) % 500_000
            };
            mapping.observe(device, host_event + delay);
            if k > 100 {
                let stamp = mapping.to_host_ns(device).expect("mapped") as i128;
                let error = stamp - host_event as i128;
                assert!(
                    (0..=60_000).contains(&error),
                    "packet {k}: error {error} ns"
                );
            }
        }
        assert_eq!(mapping.resets(), 0);
    }

    #[test]
    fn a_device_restart_starts_the_estimate_over() {
        let mut mapping = ClockMapping::new();
        mapping.observe(50_000_000_000, 1_000_000_000);
        mapping.observe(50_001_000_000, 1_001_000_100);
        // Rebooted: device time back near zero.
        let offset = mapping.observe(2_000_000, 1_003_000_000);
        assert_eq!(mapping.resets(), 1);
        assert_eq!(offset, 1_001_000_000);
        // A forward step of the device's time (PTP step) also restarts it.
        mapping.observe(2_000_000 + 10_000_000_000, 1_004_000_000);
        assert_eq!(mapping.resets(), 2);
    }
}
