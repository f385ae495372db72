//! `harvest laser`: answers `laser/scan_request` with the ALACS unit through
//! `harvest_laser::ScanService` and publishes `laser/scan_result`.

pub mod process;

pub use process::{LaserArgs, LaserProcessError};
