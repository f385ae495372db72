//! [`VacuumNodeOutput`]: what one tick of the vacuum node returns.

use super::VacuumNodeEvent;
use harvest_ipc::payloads::{ArmTarget, VacuumState, ValveGrant};

/// One tick's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct VacuumNodeOutput {
    /// Commanded position of valves 1-4 (true = open); apply the ones that changed.
    pub valve_commands: [bool; 4],
    /// True on the tick the emergency stop engaged: use the board's `close_all`.
    pub close_all: bool,
    /// Answers to publish on `vacuum/valve_grant`, per arm.
    pub grants: [Option<ValveGrant>; 2],
    /// Targets to publish on `arm1/target` / `arm2/target`.
    pub targets: [Option<ArmTarget>; 2],
    /// The state to publish on `vacuum/state`.
    pub state: VacuumState,
    /// What happened.
    pub events: Vec<VacuumNodeEvent>,
}
