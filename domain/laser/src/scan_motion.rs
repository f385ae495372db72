//! What the device did during one scan ([`ScanMotion`]): the slide's moves and travel, the
//! captures and their stamps, the time spent in the unit's exchanges. Recorded by
//! [`crate::interval_scan::IntervalScan`] from the unit's answers, so the scan's mechanical
//! time can be modelled and its processing time separated from the device's.

/// What the device did during one scan.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanMotion {
    /// Slide moves commanded.
    pub moves: usize,
    /// Total slide travel, from the position before the scan, m.
    pub slide_travel_m: f64,
    /// Images captured.
    pub captures: usize,
    /// Capture stamp of each image, in capture order, ns (the unit's clock).
    pub capture_stamps_ns: Vec<u64>,
    /// Wall time spent inside the unit's calls (device exchanges, simulated rendering), ns.
    pub device_ns: u64,
}

impl ScanMotion {
    /// Forgets the last scan (keeps the stamp buffer's capacity).
    pub fn clear(&mut self) {
        self.moves = 0;
        self.slide_travel_m = 0.0;
        self.captures = 0;
        self.capture_stamps_ns.clear();
        self.device_ns = 0;
    }
}
