//! `harvest laser`: answers `laser/scan_request` with the ALACS unit through
//! `harvest_laser::LaserTask` on the node runtime and publishes `laser/scan_result`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod process;

pub use process::{LaserArgs, LaserProcessError};
