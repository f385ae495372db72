//! harvest-arm: trajectories, tracking control and the picking cycle of one 4-DOF tube arm of
//! the dual-arm apple harvester ([dual-arm sec. 2.2, 3.2 and 3.3]), and [`node::ArmNode`],
//! the transport-free logic the `harvest arm` process runs at 200 Hz. Pure: no IPC, no clock
//! reads (time is passed in by the caller). The arm's kinematic model (Table 1, eq. 1-2) is in
//! `harvest-robot-model`, shared with the vacuum supervisor, the monitor and the simulator.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod controller;
pub mod harvest_events;
pub mod manual_motion;
pub mod node;
pub mod picking_cycle;
pub mod reported_phase;
pub mod servo_model;
pub mod task;
pub mod trajectory;
