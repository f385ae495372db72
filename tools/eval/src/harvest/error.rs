//! Errors of `harvest eval harvest`.

use std::path::PathBuf;

use harvest_arm::node::ArmNodeError;
use harvest_safety::safety_monitor::TraceError;
use harvest_sim::robot::SimRobotError;
use harvest_sim::scenario::ScenarioError;
use harvest_vacuum::node::VacuumNodeError;

/// Why a harvesting evaluation could not run.
#[derive(Debug, thiserror::Error)]
pub enum HarvestEvalError {
    /// The scenario could not be loaded.
    #[error("scenario: {0}")]
    Scenario(#[from] ScenarioError),
    /// The simulated robot refused to start or step.
    #[error("simulated robot: {0}")]
    Robot(#[from] SimRobotError),
    /// An arm node could not be built.
    #[error("{0}")]
    ArmNode(#[from] ArmNodeError),
    /// The scenario's valve box gives no pressure thresholds that tell a seal apart.
    #[error("pressure thresholds: {0}")]
    Pressure(#[from] harvest_vacuum::pressure::PressureConfigError),
    /// The vacuum node could not be built.
    #[error("{0}")]
    VacuumNode(#[from] VacuumNodeError),
    /// A simulated device refused a request the nodes made.
    #[error("{device} at {stamp_ns} ns: {message}")]
    Device {
        /// Which device.
        device: &'static str,
        /// When, ns.
        stamp_ns: u64,
        /// The device's error.
        message: String,
    },
    /// The executive's node could not be built.
    #[error("executive: {0}")]
    Executive(String),
    /// A node ended the run (its error, or a device read of the in-process robot failed).
    #[error("node: {0}")]
    Node(String),
    /// An argument is out of range.
    #[error("argument `{arg}` = {value}: {reason}")]
    InvalidArgument {
        /// The argument.
        arg: &'static str,
        /// Its value.
        value: String,
        /// What was expected.
        reason: &'static str,
    },
    /// The safety monitor refused the trace (events out of order: a bug of the runner).
    #[error("safety trace: {0}")]
    Trace(#[from] TraceError),
    /// The JSON report could not be written.
    #[error("writing {path}: {message}")]
    Write {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
}
