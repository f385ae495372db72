//! harvest-executive-node: the executive as a transport-free node of the node runtime
//! ([`harvest_node::Node`]): the operator's mode machine ([`harvest_operator::Executive`])
//! between its channels, the one writer of `safety/emergency_stop`, the platform's driver and,
//! along a row, the stop-and-go cycle ([`harvest_field::StopCycle`]).
//!
//! `harvest executive` runs it on iceoryx2 (`harvest_runtime::run_node`); `harvest eval
//! harvest|row` run it in process beside the arms and the vacuum supervisor on a simulated
//! clock (`harvest_node::Schedule`), so the evaluations see the mode, the row's field hold and
//! the emergency stop the robot sees.
//!
//! - [`node`]: [`ExecutiveNode`], its channels and its tick;
//! - [`devices`]: the platform, the tractor and the mode file behind the node contract;
//! - [`row`]: the stop cycle fed from the channels;
//! - [`messages`]: the messages built from the executive's decisions.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod devices;
pub mod messages;
pub mod node;
pub mod row;

pub use devices::{ExecutiveCommands, ExecutiveDevices, ExecutiveReadings, ModeStore};
pub use node::{ExecutiveNode, ExecutiveNodeConfig, MODE_PERIOD_NS, START_WAIT_NS};
pub use row::{RowOptions, RowWork};
