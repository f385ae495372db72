//! `harvest lidar`: the solid-state LiDAR's integrated point clouds -> `lidar/points`.

pub mod process;

pub use process::{LidarArgs, LidarProcessError};
