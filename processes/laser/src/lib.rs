//! harvest-laser: the ALACS laser scanner's algorithms (paper 000): triangulation (eq. 7-8,
//! eq. 10), laser-line extraction, per-image position candidates and their selection, the
//! interval scan, extrinsic calibration (Algorithm 1 and the section 5.1 comparison), the
//! `calibrate laser` command, and the localisation accuracy evaluation (section 5.2).
//!
//! The scan algorithms are transport-free; [`service`] answers one scan request on any ALACS
//! unit, [`process`] is the `harvest laser` process around it (IPC, heartbeats), and
//! [`refinement`] measures what the scan adds to the ToF camera's localisation
//! (`harvest eval laser`), [`policy_eval`] what perception's scan policy gains and costs
//! (`harvest eval laser --policy`).

pub mod accuracy;
pub mod calibration;
pub mod candidate;
pub mod cli;
pub mod extraction;
pub mod fusion;
pub mod observed_unit;
pub mod policy_eval;
pub mod process;
pub mod refinement;
pub mod report_table;
pub mod scan;
pub mod selection;
pub mod service;
pub mod triangulation;

pub use accuracy::{AccuracyConfig, AccuracyReport, evaluate_localization_accuracy};
pub use candidate::{CandidateConfig, PositionCandidate, TargetHint};
pub use cli::{CalibrateLaserArgs, CalibrateLaserError, run_calibrate_laser};
pub use extraction::{ExtractionConfig, LaserLineExtractor, PixelRoi, StripePoint};
pub use policy_eval::{PolicyReport, evaluate_policy};
pub use process::{LaserArgs, LaserProcessError};
pub use refinement::{
    EvalLaserArgs, EvalLaserError, RefinementReport, evaluate_refinement, run_eval_laser,
};
pub use scan::{
    ProcessorConfig, ScanConfig, ScanError, ScanPlan, ScanPlanner, ScanProcessor, ScanResult,
    run_scan,
};
pub use service::{ScanRequestError, ScanService};
pub use triangulation::{LaserTriangulator, TriangulationModel};
