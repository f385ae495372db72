//! `harvest arm --id 1|2`: one arm's 200 Hz control loop. Reads the encoders through
//! `harvest_hw::arm_servos::ArmServos`, steps `harvest_arm::node::ArmNode`, commands the servos
//! and publishes the arm's state, events and heartbeat, under the node runtime
//! (`harvest_runtime::run_node`; the arm's node and channels in `harvest_arm::task`).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod process;

pub use process::{ArmArgs, ArmDevice, ArmProcessError, run};
