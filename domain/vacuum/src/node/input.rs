//! What one tick of the vacuum node reads: [`VacuumNodeInput`] with the [`BoardReadings`], and
//! the caller's [`Reachability`] test.

use harvest_ipc::payloads::{AppleDetections, ArmState, ValveRequest};
use harvest_robot_model::ArmId;

/// One report of the valve board (the `ValveBoard::valve_states` and `pressures` of a tick).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct BoardReadings {
    /// When the board was read, ns.
    pub stamp_ns: u64,
    /// Position each valve 1-4 was last commanded to, as the board reports it.
    pub valve_open: [bool; 4],
    /// True while a gate has not reached that position yet.
    pub valve_in_transit: [bool; 4],
    /// Vacuum inside arm 1, inside arm 2 and at the source, mmH2O.
    pub pressure_mmh2o: [f32; 3],
}

/// Reachability of an apple by an arm: `(arm, apple centre in the robot frame m, radius m)`.
/// Supplied by the caller from the arm kinematics (inverse of eq. 1 within Table 1's limits).
pub type Reachability = Box<dyn Fn(ArmId, &[f64; 3], f64) -> bool + Send>;

/// One tick's inputs.
#[derive(Debug, Clone, Copy, Default)]
pub struct VacuumNodeInput<'a> {
    /// Now, ns (stack clock).
    pub now_ns: u64,
    /// Each arm's latest state, indexed by [`ArmId::index`].
    pub arm_states: [Option<&'a ArmState>; 2],
    /// Each arm's latest (standing) valve request.
    pub valve_requests: [Option<&'a ValveRequest>; 2],
    /// This tick's board readings, if read.
    pub readings: Option<BoardReadings>,
    /// A detection set received this tick.
    pub detections: Option<&'a AppleDetections>,
    /// True while the emergency stop is engaged.
    pub emergency_stop: bool,
}
