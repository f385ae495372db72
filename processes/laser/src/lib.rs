//! harvest-laser: the ALACS laser scanner's algorithms (paper 000): triangulation (eq. 7-8,
//! eq. 10), laser-line extraction, per-image position candidates and their selection, the
//! interval scan, extrinsic calibration (Algorithm 1 and the section 5.1 comparison), the
//! `calibrate laser` command, and the localisation accuracy evaluation (section 5.2).
//!
//! No IPC here: the process wiring uses [`scan::ScanPlanner`], [`scan::ScanProcessor`] and
//! [`scan::run_scan`].

pub mod accuracy;
pub mod calibration;
pub mod candidate;
pub mod cli;
pub mod extraction;
pub mod scan;
pub mod selection;
pub mod triangulation;

pub use accuracy::{AccuracyConfig, AccuracyReport, evaluate_localization_accuracy};
pub use candidate::{CandidateConfig, PositionCandidate, TargetHint};
pub use cli::{CalibrateLaserArgs, CalibrateLaserError, run_calibrate_laser};
pub use extraction::{ExtractionConfig, LaserLineExtractor, PixelRoi, StripePoint};
pub use scan::{
    ProcessorConfig, ScanConfig, ScanError, ScanPlan, ScanPlanner, ScanProcessor, ScanResult,
    run_scan,
};
pub use triangulation::{LaserTriangulator, TriangulationModel};
