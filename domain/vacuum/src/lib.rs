//! harvest-vacuum: the centralized vacuum of the dual-arm harvester ([dual-arm sec. 2.3],
//! 3.3 and 4.2), as pure logic: no I/O, no clock reads (times are passed in).
//!
//! - [`pressure`]: attachment inference from the three pressure sensors.
//! - [`policy`]: the coordination policies (2024 failure-aware, 2023, sequential baseline)
//!   behind [`policy::VacuumPolicy`].
//! - [`assignment`] and [`replan`]: apple assignment to the two arms (Algorithm 1) and its
//!   update when a new detection set arrives.
//! - [`node`]: the vacuum supervisor's logic (valves, inference, policy, assignment) without
//!   transport; the `harvest vacuum` process (crate `harvest-vacuum-process`) runs it at 200 Hz.
//! - [`harvest_events`]: the node's events as `harvest/events` messages.
//!
//! The safety monitor that judges these policies is `harvest-safety`, which does not depend on
//! this crate; the discrete-event cycle model that drives the policies against it is in
//! `harvest-eval`. The mapping from the paper's formulas to the policy state machine is in
//! `POLICY.md`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod assignment;
pub mod completion;
pub mod harvest_events;
pub mod node;
pub mod policy;
pub mod pressure;
pub mod replan;
pub mod task;
