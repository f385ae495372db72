//! `harvest perception`: `camera/rgbd` -> `perception/apples` around
//! `harvest_perception::node::PerceptionNode` (and, with the LiDAR-fused depth source,
//! `lidar/points` in; with laser refinement, `laser/scan_request` out and `laser/scan_result` in).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod process;

pub use process::{PerceptionArgs, PerceptionProcessError, build_task, run};
