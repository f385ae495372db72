//! harvest-monitor: `harvest monitor`, the independent safety monitor ([`harvest_safety`]) run
//! on the stack's channels, live or from a recording.
//!
//! The checker itself is [`harvest_safety::safety_monitor::SafetyMonitor`], which judges a
//! stream of [`harvest_safety::trace::TraceEvent`]s and shares no logic with the policies. This
//! crate only turns what the stack publishes into those events and feeds them:
//!
//! - [`mapping`]: the one place where stack channels become trace events (`vacuum/state`,
//!   `arm{1,2}/command`, `arm{1,2}/state`, `safety/emergency_stop`);
//! - [`stack_monitor`]: mapping + checker + counts, fed message by message;
//! - [`recording`]: the same over an MCAP recording (the recorder's scanner and the payload
//!   codec);
//! - [`live`]: the same on a running stack (subscribers woken by the wait set), publishing each
//!   violation on `safety/violation` in the stack ([`violation_message`]);
//! - [`args`]: the command line and [`args::run_monitor`].

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod args;
pub mod error;
pub mod live;
pub mod mapping;
pub mod recording;
pub mod stack_monitor;
pub mod violation_message;
pub mod violation_outlet;

pub use args::{MonitorArgs, run_monitor};
pub use error::MonitorError;
pub use stack_monitor::{MonitorReport, StackMonitor};

#[cfg(test)]
mod tests;
