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
    Starting = 0,
    Running = 1,
    Degraded = 2,
    Stopping = 3,
    /// Failed for good and not restarted any more: published by the supervisor on behalf of a
    /// non-critical process whose failure did not stop the stack.
    Failed = 4,
}

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
)]
#[type_name("harvest.ProcessHealth.v2")]
pub struct ProcessHealth {
    pub header: Header,
    /// The name the process was launched under (launch-file name).
    pub process_name: FixedString<32>,
    pub pid: u32,
    pub run_state: WireCode<ProcessRunState>,
    pub _reserved: [u8; 3],
    /// Messages the process has handled on its main channel since start (published for
    /// producers, received for consumers): the supervisor derives a rate from it.
    pub main_channel_count: u64,
    /// A free-form figure the process cares about (perception: last receive latency in ns).
    pub detail_value: u64,
    pub detail: FixedString<32>,
    /// Control loops: ticks whose deadline passed since start
    /// ([`crate::period_stats::PeriodSummary::deadline_misses`]); 0 for other processes.
    /// (Added in version 2.)
    pub deadline_misses: u64,
}

crate::serde_payload!(
    ProcessHealth,
    "harvest.ProcessHealth",
    2,
    "encoding bincode2-fixint-le: header: {msg_seq:u64, capture_ns:u64, publish_ns:u64}; \
process_name: u64 length + UTF-8; pid:u32; run_state:u8 (0 starting,1 running,2 degraded,3 \
stopping,4 failed); _reserved:[u8;3]; main_channel_count:u64; detail_value:u64; detail: u64 length + UTF-8; deadline_misses:u64"
);
