//! `harvest vacuum`: the vacuum supervisor's 200 Hz loop. Owns the valve board through
//! `harvest_hw::valve_board::ValveBoard`, steps `harvest_vacuum::node::VacuumNode` and publishes
//! the vacuum state, grants, arm targets, events and heartbeat.

pub mod policy_arg;
pub mod process;
