//! `harvest lidar`: the solid-state LiDAR's integrated point clouds -> `lidar/points`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod process;

pub use process::{LidarArgs, LidarProcessError};
