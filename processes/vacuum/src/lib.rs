//! harvest-vacuum: the centralized vacuum of the dual-arm harvester (paper 003, sections 2.3,
//! 3.3 and 4.2), as pure logic: no I/O, no clock reads (times are passed in).
//!
//! - [`pressure`]: attachment inference from the three pressure sensors.
//! - [`policy`]: the coordination policies (2024 failure-aware, 2023, sequential baseline)
//!   behind [`policy::VacuumPolicy`].
//! - [`assignment`] and [`replan`]: apple assignment to the two arms (Algorithm 1) and its
//!   update when a new detection set arrives.
//! - [`cycle_model`]: a discrete-event model of the picking timeline driven by the policies
//!   (Fig. 12, single vs. dual arm with injected failures).
//! - [`trace`] and [`safety_monitor`]: time-stamped observations and an independent checker.
//! - [`node`]: the vacuum supervisor process's logic (valves, inference, policy, assignment)
//!   without transport.
//! - [`process`]: the `harvest vacuum` process running the node over the channels at 200 Hz;
//!   [`harvest_events`] turns its events into `harvest/events` messages and [`harvest_log`]
//!   turns those into per-apple lines and the harvest summary (`harvest up`).
//!
//! The mapping from the paper's formulas to the policy state machine is in `POLICY.md`.

pub mod arm_id;
pub mod arm_phase;
pub mod assignment;
pub mod cycle_model;
pub mod harvest_events;
pub mod harvest_log;
pub mod node;
pub mod policy;
pub mod policy_arg;
pub mod pressure;
pub mod process;
pub mod replan;
pub mod safety_monitor;
pub mod trace;

pub use arm_id::ArmId;
pub use arm_phase::ArmPhase;

#[cfg(test)]
mod property_tests;
