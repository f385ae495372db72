//! `harvest vacuum`: the vacuum supervisor's 200 Hz loop. Owns the valve board through
//! `harvest_hw::valve_board::ValveBoard`, steps `harvest_vacuum::node::VacuumNode` and publishes
//! the vacuum state, grants, arm targets, events and heartbeat, under the node runtime
//! (`harvest_runtime::run_node`; the node and its channels in `harvest_vacuum::task`).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod policy_arg;
pub mod process;
