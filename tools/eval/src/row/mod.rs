//! `harvest eval row`: orchard rows worked stop by stop under a simulated clock, with
//! perception in the loop ([dual-arm sec. 2.2, 4.1-4.3]).
//!
//! The stop-and-go sequencer is the executive's own ([`harvest_field::StopCycle`], with
//! [`harvest_field::choose_offsets`] choosing the platform offsets); the harvesting is
//! `harvest eval harvest`'s episode ([`crate::harvest::Episode`]: the arm and vacuum nodes on
//! the simulated robot through the device traits), here on a row's world that moves with the
//! simulated trailer and platform stages; the detections are perception's own node on frames
//! the simulator renders at a reduced rate ([`perception_loop`]). Each row is run with every
//! seed, with arm 1 alone and with both arms, and scored against the ground truth
//! ([`truth`]): the structure of Table 2 (success, cycle time per attempt), of Table 3
//! (failure causes, perception's included) and the platform positioning's gain.
//!
//! - [`args`]: the command line; [`report::run_eval_row`] runs it.
//! - [`runner`]: one row, tick by tick.
//! - [`perception_loop`]: when frames are rendered, and the detection sets.
//! - [`truth`]: reach from the ground truth, Table 3 attribution.
//! - [`failures`]: the ground truth behind each failed attempt (`--failures`).

pub mod args;
pub mod error;
pub mod failures;
pub mod perception_loop;
pub mod report;
pub mod runner;
pub mod truth;

pub use args::{DetectionsArg, EvalRowArgs};
pub use error::RowEvalError;
pub use report::{RowEvalReport, run_eval_row};
pub use runner::{RowOutcome, RowRunConfig, run_row};

#[cfg(test)]
mod tests;
