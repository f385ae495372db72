//! `harvest eval laser`: what the ALACS scan adds to the ToF camera's localisation
//! ([`refinement`]), what perception's scan policy gains and costs ([`policy_eval`]), and the
//! localisation accuracy of a calibrated unit over the paper's protocol ([`accuracy`]).

pub mod accuracy;
pub mod policy_eval;
pub mod refinement;
pub mod report_table;

pub use accuracy::{AccuracyConfig, AccuracyReport, evaluate_localization_accuracy};
pub use policy_eval::{PolicyReport, evaluate_policy};
pub use refinement::{
    EvalLaserArgs, EvalLaserError, RefinementReport, evaluate_refinement, run_eval_laser,
};
