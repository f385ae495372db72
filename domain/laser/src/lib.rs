//! harvest-laser: the ALACS laser scanner's algorithms: triangulation ([alacs eq. 7-8,
//! eq. 10]), laser-line extraction, per-image position candidates and their selection, the
//! interval scan ([alacs sec. 3]), extrinsic calibration ([alacs Algorithm 1] and the comparison
//! of [alacs sec. 5.1]).
//!
//! Transport-free: [`service`] answers one scan request on any ALACS unit, blocking or one
//! device exchange at a time ([`interval_scan`]); [`task`] is the laser's node, which the
//! `harvest laser` process (crate `harvest-laser-process`) runs on the node runtime with the
//! unit as its devices ([`unit_devices`]). The calibration command is in `harvest-calibrate`,
//! the evaluations (`harvest eval laser`) in `harvest-eval`.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod calibration;
pub mod candidate;
pub mod extraction;
pub mod fusion;
pub mod interval_scan;
pub mod reach;
pub mod scan;
pub mod scan_counts;
pub mod scan_motion;
pub mod selection;
pub mod service;
pub mod task;
pub mod triangulation;
pub mod unit_devices;

pub use candidate::{CandidateConfig, PositionCandidate, TargetHint};
pub use extraction::{ExtractionConfig, LaserLineExtractor, PixelRoi, StripePoint};
pub use reach::{InReach, LaserReach, ReachError};
pub use scan::{
    ProcessorConfig, ScanConfig, ScanError, ScanPlan, ScanPlanner, ScanProcessor, ScanResult,
    run_scan,
};
pub use service::{ScanRequestError, ScanService};
pub use task::LaserTask;
pub use triangulation::{LaserTriangulator, TriangulationModel};
pub use unit_devices::UnitDevices;
