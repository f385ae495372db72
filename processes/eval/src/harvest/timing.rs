//! Hardware timing profiles of the simulated robot.
//!
//! Fig. 12 of paper 003 rests on phase times averaged in the field: one arm movement (approach
//! or retract) about 2.0 s and attach + release about 0.5 s together (derivation in
//! `processes/arm/CONTROLLER.md` and `processes/vacuum/POLICY.md`: baseline 2M + A + R = 4.5 s,
//! 2023 A + M + R = 2.5 s). In the full loop the attach and release phases contain the butterfly
//! gates' travel and the tube's pressure lag, which the scenario files set to 0.6 s and 0.12 s
//! (the paper says only "less than one second"). [`TimingArg::Fig12`] shortens those so that
//! attach + release come out near 0.5 s; it changes nothing else (arm speed, trajectories,
//! policies and thresholds are the same in both profiles).

use harvest_sim::scenario::Scenario;

use super::args::TimingArg;

/// Gate travel of the Fig. 12 profile, s.
pub const FIG12_VALVE_TRAVEL_S: f64 = 0.1;
/// Arm tube pressure time constant of the Fig. 12 profile, s.
pub const FIG12_LINE_TIME_CONSTANT_S: f64 = 0.03;
/// Source pressure time constant of the Fig. 12 profile, s.
pub const FIG12_SOURCE_TIME_CONSTANT_S: f64 = 0.06;

/// Applies `timing` to `scenario`'s hardware constants.
pub fn apply_timing(scenario: &mut Scenario, timing: TimingArg) {
    match timing {
        TimingArg::Scenario => {}
        TimingArg::Fig12 => {
            scenario.vacuum.valve_travel_time_s = FIG12_VALVE_TRAVEL_S;
            scenario.vacuum.line_time_constant_s = FIG12_LINE_TIME_CONSTANT_S;
            scenario.vacuum.source_time_constant_s = FIG12_SOURCE_TIME_CONSTANT_S;
        }
    }
}
