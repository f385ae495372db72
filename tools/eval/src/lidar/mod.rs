//! `harvest eval lidar`: the Table-III-style repeatability of fused versus ToF localization in
//! the simulated orchard, and the fusion time.

pub mod evaluation;

pub use evaluation::{EvalLidarArgs, run_eval_lidar};
