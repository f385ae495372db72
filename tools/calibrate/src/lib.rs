//! harvest-calibrate: `harvest calibrate laser|lidar-camera`, the calibration commands with their
//! method comparisons and reports, and the generators of calibration data (the ALACS samples of
//! the [alacs sec. 5.1] protocol, checkerboard scenes rendered in the simulated orchard). A tool
//! beside the onboard stack: the fits themselves are in `harvest-laser` (Algorithm 1) and here
//! (LiDAR-camera, eq. 3); the files they write are read onboard through `harvest-laser` and
//! `harvest-lidar`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod laser;
pub mod laser_samples;
pub mod lidar;

pub use laser::{CalibrateLaserArgs, CalibrateLaserError, run_calibrate_laser};
pub use lidar::{CalibrateLidarCameraArgs, run_calibrate_lidar_camera};

#[cfg(test)]
mod laser_calibration_tests;
