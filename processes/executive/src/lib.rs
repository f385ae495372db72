//! `harvest executive`: the one place that enforces the operator's mode. Runs
//! `harvest_operator::Executive` at a fixed rate, answers `operator/command` on `operator/ack`,
//! publishes `operator/mode`, is the one writer of `safety/emergency_stop`, forwards manual
//! moves to the arms (`armN/manual`), drives the platform and, along a row, the stop-and-go
//! cycle ([`row`]).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod ctl;
pub mod process;
pub mod row;

pub use process::{ExecutiveArgs, ExecutiveProcessError, run};
