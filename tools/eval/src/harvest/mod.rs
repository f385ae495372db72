//! `harvest eval harvest`: the robot's harvesting nodes run in one process on a simulated
//! clock against the simulated robot, scored against the simulator's ground truth
//! ([dual-arm sec. 3.2-3.3 and 4.2]: Fig. 12 cycle times, Table 2 success counts, single- vs
//! dual-arm cycle time per attempt).
//!
//! The nodes are the processes' own, with their glue: the executive
//! ([`harvest_executive_node::ExecutiveNode`]), each arm ([`harvest_arm::task::ArmTask`]) and
//! the vacuum supervisor ([`harvest_vacuum::task::VacuumTask`], which also assigns the apples
//! and decides when the harvest is complete), each under the robot's tick
//! ([`harvest_node::Runner`]) on an in-process schedule ([`harvest_node::Schedule`]). They
//! reach the simulated robot ([`harvest_sim::robot::SimRobot`]) through the hardware traits
//! (`ArmServos`, `ValveBoard`) implemented in process by [`devices`]. Detections come from the
//! ground truth through the camera's depth-noise model ([`detections`]), not from perception's
//! pipeline, which `harvest eval perception` evaluates. Every run feeds the independent safety
//! monitor ([`safety`]).
//!
//! - [`args`]: the command line; [`report::run_eval_harvest`] runs it.
//! - [`runner`]: one episode, period by period; also measures the emergency-stop reaction.
//! - [`records`]: event log, attempts, per-apple records, failure causes.
//! - [`timing`]: the hardware timing profiles (scenario constants, or Fig. 12's phase times).
//! - [`calibration`]: the pressure thresholds derived from the simulated valve box.

pub mod args;
pub mod calibration;
pub mod detections;
pub mod devices;
pub mod error;
pub mod records;
pub mod report;
pub mod runner;
pub mod safety;
pub mod timing;

pub use args::{EvalHarvestArgs, PolicyArg, TimingArg};
pub use error::HarvestEvalError;
pub use report::{HarvestReport, HarvestSummary, run_eval_harvest};
pub use runner::{
    DetectionFeed, EmergencyStopReaction, Episode, EpisodeConfig, EpisodeOutcome, ModeFeed,
    run_episode,
};

#[cfg(test)]
mod tests;
