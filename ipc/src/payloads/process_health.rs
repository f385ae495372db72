//! Heartbeats: every process reports twice a second; the supervisor restarts a silent one.

use crate::fixed_string::FixedString;
use crate::header::Header;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Run state of a process (code in [`ProcessHealth::run_state`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum ProcessRunState {
    /// Setting up (opening channels and devices).
    Starting = 0,
    /// Working normally.
    Running = 1,
    /// Working, but something is wrong (a device error, a missed input); see the heartbeat's
    /// other fields.
    Degraded = 2,
    /// Shutting down after a stop request.
    Stopping = 3,
    /// Failed for good and not restarted any more: published by the supervisor on behalf of a
    /// non-critical process whose failure did not stop the stack.
    Failed = 4,
}

/// The kind of a device error, as a heartbeat carries it (code in
/// [`ProcessHealth::last_device_error`]). One code per `harvest_hw::ErrorKind` (which maps to it),
/// plus `None`.
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum DeviceErrorCode {
    /// No device error since the process started.
    None = 0,
    /// The device is gone (cable, serial port closed, simulator dead).
    Disconnected = 1,
    /// The device did not answer in time.
    Timeout = 2,
    /// The device answered with a fault of its own (over-current, limit switch, sensor error).
    Fault = 3,
    /// The device answered with bytes that could not be parsed.
    Protocol = 4,
    /// The request was refused before reaching the device (out of range, wrong state).
    Refused = 5,
    /// Any other failure.
    Other = 6,
}

impl DeviceErrorCode {
    /// The code's name as status lines print it (`timeout`, `disconnected`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Disconnected => "disconnected",
            Self::Timeout => "timeout",
            Self::Fault => "fault",
            Self::Protocol => "protocol",
            Self::Refused => "refused",
            Self::Other => "other",
        }
    }
}

impl std::fmt::Display for DeviceErrorCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One heartbeat of a process on `system/health`, twice a second.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.ProcessHealth.v3")]
pub struct ProcessHealth {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The name the process was launched under (launch-file name).
    pub process_name: FixedString<32>,
    /// The process id.
    pub pid: u32,
    /// What the process is doing.
    pub run_state: WireCode<ProcessRunState>,
    /// The kind of the last error a device driver of the process returned
    /// ([`DeviceErrorCode::None`]: none since start). Set by the process
    /// ([`crate::health::HealthReporter::note_device_error`]) from the driver's
    /// `harvest_hw::ErrorKind`, so the supervisor and the console can tell a timeout from a
    /// disconnect, a device fault or a refused request. (Added in version 3.)
    pub last_device_error: WireCode<DeviceErrorCode>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// Messages the process has handled on its main channel since start (published for
    /// producers, received for consumers): the supervisor derives a rate from it.
    pub main_channel_count: u64,
    /// A free-form figure the process cares about (perception: last receive latency in ns).
    pub detail_value: u64,
    /// The name of `detail_value` (`period_p99_us`, `latency_ns`; empty: none).
    pub detail: FixedString<32>,
    /// Control loops: ticks whose deadline passed since start
    /// ([`crate::period_stats::PeriodSummary::deadline_misses`]); 0 for other processes.
    /// (Added in version 2.)
    pub deadline_misses: u64,
}
