//! What the laser has answered so far ([`ScanCounts`]): the heartbeat's figures and the last
//! log line of the process.

use harvest_ipc::payloads::{LaserScanResult, LaserScanStatus, ProcessRunState};

/// Answers given so far, by outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScanCounts {
    /// Requests answered (every status).
    pub answered: u64,
    /// Answers with a measured position (status Ok).
    pub refined: u64,
    /// Answers with status DeviceError because the device failed (or the scan could not be
    /// set up).
    pub device_errors: u64,
    /// Answers with status DeviceError because the emergency stop ended or refused the scan.
    pub stopped: u64,
    /// Duration of the last answer, ns.
    pub last_scan_ns: u64,
    /// The last answer not given by the stop failed on the device.
    last_failed_on_device: bool,
}

impl ScanCounts {
    /// Counts `result`; `stopped`: the emergency stop ended or refused its scan.
    pub fn count(&mut self, result: &LaserScanResult, stopped: bool) {
        self.answered += 1;
        self.refined += u64::from(result.status == LaserScanStatus::Ok);
        let device_error = result.status == LaserScanStatus::DeviceError;
        self.device_errors += u64::from(device_error && !stopped);
        self.stopped += u64::from(stopped);
        self.last_scan_ns = result.scan_duration_ns;
        if !stopped {
            self.last_failed_on_device = device_error;
        }
    }

    /// Degraded while the last scan failed on the device (an answer of the stop changes
    /// nothing: it says nothing about the device).
    pub fn run_state(&self) -> ProcessRunState {
        if self.last_failed_on_device {
            ProcessRunState::Degraded
        } else {
            ProcessRunState::Running
        }
    }
}
