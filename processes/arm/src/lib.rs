//! harvest-arm: kinematics, trajectories, tracking control and the picking cycle of one 4-DOF
//! tube arm of the dual-arm apple harvester (paper 003, sections 2.2, 3.2 and 3.3). The logic
//! modules are pure (no IPC, no clock reads; time is passed in by the caller); [`process`] is the
//! `harvest arm` process that runs [`node::ArmNode`] over the channels at 200 Hz.

pub mod clearance;
pub mod control_loop;
pub mod controller;
pub mod failure_streak;
pub mod harvest_events;
pub mod joint;
pub mod kinematics;
pub mod node;
pub mod params;
pub mod period_stats;
pub mod picking_cycle;
pub mod process;
pub mod servo_model;
pub mod trajectory;
