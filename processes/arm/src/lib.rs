//! harvest-arm: kinematics, trajectories, tracking control and the picking cycle of one 4-DOF
//! tube arm of the dual-arm apple harvester (paper 003, sections 2.2, 3.2 and 3.3). Pure logic:
//! no IPC and no clock reads; time is passed in by the caller.

pub mod clearance;
pub mod controller;
pub mod joint;
pub mod kinematics;
pub mod node;
pub mod params;
pub mod picking_cycle;
pub mod servo_model;
pub mod trajectory;
