//! The vacuum supervisor's pressure thresholds for the simulated valve box.
//!
//! The attachment inference (`harvest_vacuum::pressure`) derives its ratio thresholds from a
//! [`ValveLineModel`] (the conductance divider of inlet and cup). The simulator implements the
//! same linear-conductance model with the scenario's `VacuumConfig`; [`line_model`] reads the
//! model off the scenario, so the thresholds of an evaluation follow the simulated hardware by
//! one formula, and the test below pins the simulator's default constants to the nominal line
//! the live vacuum process uses ([`ValveLineModel::NOMINAL`]).

use harvest_sim::scenario::VacuumConfig;
use harvest_vacuum::pressure::{PressureConfig, PressureConfigError, ValveLineModel};

/// The valve line of the simulated valve box.
pub fn line_model(vacuum: &VacuumConfig) -> ValveLineModel {
    ValveLineModel {
        inlet_conductance: vacuum.inlet_conductance,
        open_cup_conductance: vacuum.open_cup_conductance,
        leaf_blocked_cup_conductance: vacuum.leaf_blocked_cup_conductance,
        sealed_cup_conductance: vacuum.sealed_cup_conductance,
    }
}

/// `pressure` with the ratio thresholds of the simulated valve box (every other field kept).
pub fn pressure_for(
    vacuum: &VacuumConfig,
    pressure: PressureConfig,
) -> Result<PressureConfig, PressureConfigError> {
    let (seal_ratio_on, seal_ratio_off) = line_model(vacuum).ratio_thresholds()?;
    Ok(PressureConfig {
        seal_ratio_on,
        seal_ratio_off,
        ..pressure
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::scenario::{Scenario, preset_names};

    #[test]
    fn the_simulated_valve_box_is_the_nominal_line_in_every_preset() {
        assert_eq!(
            line_model(&VacuumConfig::default()),
            ValveLineModel::NOMINAL
        );
        for name in preset_names() {
            let scenario = Scenario::preset(name).expect("preset");
            let line = line_model(&scenario.vacuum);
            assert_eq!(line, ValveLineModel::NOMINAL, "preset {name}");
            let derived = pressure_for(&scenario.vacuum, PressureConfig::default()).expect("ok");
            assert_eq!(derived, PressureConfig::default(), "preset {name}");
        }
    }

    #[test]
    fn the_thresholds_separate_the_simulated_levels() {
        let vacuum = VacuumConfig::default();
        let p = pressure_for(&vacuum, PressureConfig::default()).expect("ok");
        let ratio = |cup: f64| vacuum.inlet_conductance / (vacuum.inlet_conductance + cup);
        let (on, off) = (f64::from(p.seal_ratio_on), f64::from(p.seal_ratio_off));
        // A cup that lost its apple reads below `off` (the loss is detected) ...
        assert!(ratio(vacuum.open_cup_conductance) < off);
        // ... a leaf-blocked cup never reads sealed, a sealed one does.
        assert!(ratio(vacuum.leaf_blocked_cup_conductance) < off);
        assert!(off < on && on < ratio(vacuum.sealed_cup_conductance));
        assert_eq!(p.validate(), Ok(()));
    }
}
