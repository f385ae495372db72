//! `harvest laser`: answers `laser/scan_request` with the ALACS unit through
//! `harvest_laser::ScanService` and publishes `laser/scan_result`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod process;

pub use process::{LaserArgs, LaserProcessError};
