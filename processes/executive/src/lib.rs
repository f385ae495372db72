//! `harvest executive`: the one place that enforces the operator's mode. Runs
//! `harvest_executive_node::ExecutiveNode` (`harvest_operator::Executive` over its channels)
//! on the node runtime: answers `operator/command` on `operator/ack`, publishes
//! `operator/mode`, is the one writer of `safety/emergency_stop`, forwards manual moves to the
//! arms (`armN/manual`), drives the platform and, along a row, the stop-and-go cycle. Also
//! `harvest ctl` ([`ctl`]), the terminal client.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod ctl;
pub mod process;

pub use process::{ExecutiveArgs, ExecutiveProcessError, run};
