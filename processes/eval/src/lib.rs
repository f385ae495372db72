//! harvest-eval: evaluations of the stack against the simulator's ground truth.
//!
//! [`perception`]: `harvest eval perception` runs the perception process's own
//! [`harvest_perception::node::PerceptionNode`] on frames rendered by the simulator and scores
//! its detections and 3D positions against the simulated world's ground truth.
//!
//! [`harvest`]: `harvest eval harvest` runs the arm and vacuum processes' logic in process on a
//! simulated clock against the simulated robot and scores the harvest (cycle times, success).

pub mod harvest;
pub mod perception;

pub use perception::{EvalError, EvalPerceptionArgs, PerceptionReport, run_eval_perception};
