//! `harvest eval perception`: the perception process's own node, scored against the simulator.
//!
//! For every frame `i` of a scenario, the world of seed `seed + i` is generated, its colour and
//! depth images are rendered into the camera's wire format ([`frame`]) and every selected
//! estimator's [`harvest_perception::node::PerceptionNode`] processes the same frame, timed on
//! this one thread. Each reported apple is matched to the world's true apples by the rule in
//! [`matching`] (2D overlap with the label render, then a 3D gate, one to one by distance), with
//! per-apple visibility and failure conditions from [`truth`]. The same scenario with its apples
//! removed gives frames on which every reported apple is false. [`report`] aggregates, [`tables`]
//! prints.
//!
//! Perception is given the true camera pose (`robot_from_camera` = the renderer's
//! `robot_from_color`): the evaluation measures perception, not extrinsic calibration.

pub mod args;
pub mod error;
pub mod frame;
#[cfg(test)]
mod glare_tests;
pub mod lidar_capture;
pub mod matching;
pub mod records;
pub mod report;
pub mod run;
pub mod stats;
pub mod tables;
pub mod truth;

pub use args::EvalPerceptionArgs;
pub use error::EvalError;
pub use report::PerceptionReport;
pub use run::{evaluate, run_eval_perception};
