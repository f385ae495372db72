//! harvest-eval: evaluations of the stack against the simulator's ground truth.
//!
//! - [`perception`]: `harvest eval perception` runs the perception process's own
//!   `harvest_perception::node::PerceptionNode` on frames rendered by the simulator and scores
//!   its detections and 3D positions against the simulated world's ground truth.
//! - [`harvest`]: `harvest eval harvest` runs the arm and vacuum processes' logic in process on
//!   a simulated clock against the simulated robot and scores the harvest (cycle times, success).
//! - [`row`]: `harvest eval row` works orchard rows stop by stop (the executive's
//!   `harvest_field::StopCycle`, platform positioning, tractor) on the same simulated clock,
//!   with perception on rendered frames in the loop, single vs dual arm (Tables 2 and 3).
//! - [`laser`]: `harvest eval laser`, what the ALACS scan adds and the scan policy costs.
//! - [`lidar`]: `harvest eval lidar`, fused versus ToF localization (Table III).
//! - [`detector_dataset`]: `harvest dataset detector`, domain-randomised renders with exact
//!   labels for training a learned detector (tools/detector_training/).
//! - [`cycle_model`]: a discrete-event model of the picking timeline driven by the coordination
//!   policies (Fig. 12, single vs. dual arm with injected failures), judged by the safety
//!   monitor in its property tests; `cycle_report` prints its figures.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod cycle_model;
pub mod detector_dataset;
pub mod harvest;
pub mod laser;
pub mod lidar;
pub mod perception;
pub mod row;

pub use perception::{EvalError, EvalPerceptionArgs, PerceptionReport, run_eval_perception};
