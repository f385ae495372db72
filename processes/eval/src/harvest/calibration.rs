//! The vacuum supervisor's pressure thresholds calibrated to the simulated valve box.
//!
//! The attachment inference (`harvest_vacuum::pressure`) compares the arm tube's vacuum to the
//! source's. Its defaults assume an open cup reads "a small fraction" of the source and put the
//! hysteresis band at 0.60-0.80. In the simulator's linear-conductance model (`harvest_sim`
//! `physics::vacuum`), an arm whose source valve is open reads
//! `g_inlet / (g_inlet + g_cup)` of the source: 0.99 sealed, 0.71 with a leaf under the cup,
//! but 0.625 with the cup open to the air (scenario defaults: inlet 0.5, open cup 0.3). 0.625
//! lies inside the default band, so a sealed apple that slips off the cup keeps reading
//! "sealed": the loss is never detected, the valve stays open and the arm "releases" nothing at
//! the drop-off. [`calibrated_pressure`] moves the falling threshold to the middle between the
//! open-cup ratio and the rising threshold, as one would calibrate the real board against its
//! sensors; the rising threshold (0.80) already separates sealed from open and leaf-blocked.

use harvest_sim::scenario::VacuumConfig;
use harvest_vacuum::pressure::PressureConfig;

/// Ratio of the arm vacuum to the source vacuum with the source valve fully open and a cup of
/// conductance `cup` (vent closed), in the simulator's model.
pub fn open_valve_ratio(vacuum: &VacuumConfig, cup: f64) -> f64 {
    vacuum.inlet_conductance / (vacuum.inlet_conductance + cup)
}

/// `pressure` with `seal_ratio_off` halfway between the open-cup ratio of `vacuum` and
/// `seal_ratio_on` (unchanged when the default already lies above the open-cup ratio with that
/// margin).
pub fn calibrated_pressure(vacuum: &VacuumConfig, pressure: PressureConfig) -> PressureConfig {
    let open = open_valve_ratio(vacuum, vacuum.open_cup_conductance) as f32;
    let off = 0.5 * (open + pressure.seal_ratio_on);
    PressureConfig {
        seal_ratio_off: pressure.seal_ratio_off.max(off),
        ..pressure
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_falling_threshold_separates_an_open_cup_from_a_seal() {
        let vacuum = VacuumConfig::default();
        let open = open_valve_ratio(&vacuum, vacuum.open_cup_conductance);
        let sealed = open_valve_ratio(&vacuum, vacuum.sealed_cup_conductance);
        assert!((open - 0.625).abs() < 1e-12);
        assert!(sealed > 0.98);
        let defaults = PressureConfig::default();
        assert!(
            f64::from(defaults.seal_ratio_off) < open,
            "the flaw being fixed"
        );
        let calibrated = calibrated_pressure(&vacuum, defaults);
        assert!(f64::from(calibrated.seal_ratio_off) > open);
        assert!(calibrated.seal_ratio_off < calibrated.seal_ratio_on);
        assert_eq!(calibrated.validate(), Ok(()));
    }
}
