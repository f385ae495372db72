//! harvest-safety: the independent safety monitor (the safety requirements of the coordination,
//! [dual-arm eq. 7-12]). It judges a stream of time-stamped observations ([`trace`]) and
//! shares no logic with the coordination policies it judges: this crate does not depend on
//! `harvest-vacuum`, so the monitor is never compiled with what it checks.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod safety_monitor;
pub mod trace;

pub use safety_monitor::{MonitorConfig, SafetyMonitor, Violation, check_trace};
pub use trace::{JointId, TraceEvent};
