//! The centralized vacuum: one source, two arm lines, four butterfly valves ([dual-arm sec.
//! 2.3, Fig. 3]).
//!
//! Valve numbering follows the paper: valve 1 connects arm 1's line to the source (attach),
//! valve 2 vents arm 1's line to the atmosphere (release); valves 3 and 4 do the same for arm 2.
//! `Open_Valve_i` of the coordination logic (section 3.3) is "inlet open, vent closed".
//!
//! Model (all vacuum values in mmH2O below atmosphere, flows in m^3/h):
//! - the source follows a linear fan curve `Q = Q_max (1 - P_s / P_max)`;
//! - every flow path is a linear conductance `Q = g * (pressure difference)`; a butterfly valve's
//!   conductance is proportional to its opening, which ramps at `1 / valve_travel_time_s`;
//! - arm line `i` balances inflow through its cup (`g_cup`) and vent (`g_vent`) against outflow to
//!   the source (`g_in`): `P_i = g_in / (g_in + g_cup + g_vent) * P_s`;
//! - the source balances the fan against all inflows:
//!   `P_s = P_max Q_max / (Q_max + P_max (G_leak + sum_i g_in (g_cup + g_vent) / (g_in + g_cup + g_vent)))`;
//! - each pressure relaxes to that equilibrium with a first-order lag (line and source volumes).
//!
//! An arm open to both the source and the air (cup without a fruit) therefore lowers the source
//! pressure and with it the other arm's pressure: the reason the coordination policy lets only one
//! arm attach at a time.

use crate::scenario::VacuumConfig;

/// Index of arm `arm`'s inlet valve (to the source) in the 4-valve arrays.
pub fn inlet_valve(arm: usize) -> usize {
    2 * arm
}

/// Index of arm `arm`'s vent valve (to the atmosphere) in the 4-valve arrays.
pub fn vent_valve(arm: usize) -> usize {
    2 * arm + 1
}

/// Pressures and valve positions of the simulated vacuum plant: the physical state this model
/// integrates (continuous valve openings, pressures as `f64`). Not the `vacuum/state` payload
/// `harvest_ipc::payloads::VacuumState`, which is what the vacuum supervisor reports (commanded
/// valves, sensor readings, inferred attachment, active policy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VacuumPlantState {
    /// Opening of valves 1-4, 0 = shut, 1 = fully open.
    pub valve_opening: [f64; 4],
    /// Vacuum at the source sensor, mmH2O.
    pub source_mmh2o: f64,
    /// Vacuum inside arm 1 and arm 2 (their sensors), mmH2O.
    pub arm_mmh2o: [f64; 2],
}

impl VacuumPlantState {
    /// Source at full vacuum, both arms vented (inlets shut, vents open).
    pub fn at_rest(config: &VacuumConfig) -> Self {
        Self {
            valve_opening: [0.0, 1.0, 0.0, 1.0],
            source_mmh2o: config.source_max_vacuum_mmh2o,
            arm_mmh2o: [0.0; 2],
        }
    }

    /// Advances valve positions and pressures by `dt_s` given the valve commands (true = open)
    /// and each arm's cup conductance (depends on whether a fruit seals it).
    pub fn step(
        &mut self,
        config: &VacuumConfig,
        dt_s: f64,
        valve_open: [bool; 4],
        cup_conductance: [f64; 2],
    ) {
        let travel = dt_s / config.valve_travel_time_s;
        for (opening, open) in self.valve_opening.iter_mut().zip(valve_open) {
            let target = if open { 1.0 } else { 0.0 };
            *opening += (target - *opening).clamp(-travel, travel);
        }
        let mut admittance = config.source_leak_conductance;
        let mut share = [0.0; 2];
        for arm in 0..2 {
            let g_in = config.inlet_conductance * self.valve_opening[inlet_valve(arm)];
            let g_out = cup_conductance[arm]
                + config.vent_conductance * self.valve_opening[vent_valve(arm)];
            let total = g_in + g_out;
            if total > 0.0 {
                share[arm] = g_in / total;
                admittance += g_in * g_out / total;
            }
        }
        let p_max = config.source_max_vacuum_mmh2o;
        let q_max = config.source_max_flow_m3_per_h;
        let source_target = p_max * q_max / (q_max + p_max * admittance);
        let source_blend = 1.0 - (-dt_s / config.source_time_constant_s).exp();
        let line_blend = 1.0 - (-dt_s / config.line_time_constant_s).exp();
        self.source_mmh2o += (source_target - self.source_mmh2o) * source_blend;
        for (pressure, share) in self.arm_mmh2o.iter_mut().zip(share) {
            *pressure += (share * self.source_mmh2o - *pressure) * line_blend;
        }
    }

    /// Holding force of a sealed cup on arm `arm`, newtons: suction force scales with vacuum,
    /// `F = F_max * P_arm / P_max` (the cup's effective area times the pressure difference).
    pub fn holding_force_n(&self, config: &VacuumConfig, arm: usize) -> f64 {
        config.suction_force_at_max_vacuum_n * self.arm_mmh2o[arm] / config.source_max_vacuum_mmh2o
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settle(
        state: &mut VacuumPlantState,
        config: &VacuumConfig,
        valves: [bool; 4],
        cups: [f64; 2],
    ) {
        for _ in 0..2000 {
            state.step(config, 0.005, valves, cups);
        }
    }

    #[test]
    fn closed_inlets_keep_the_source_at_its_maximum() {
        let config = VacuumConfig::default();
        let mut state = VacuumPlantState::at_rest(&config);
        settle(
            &mut state,
            &config,
            [false, true, false, true],
            [config.open_cup_conductance; 2],
        );
        let expected = config.source_max_vacuum_mmh2o * config.source_max_flow_m3_per_h
            / (config.source_max_flow_m3_per_h
                + config.source_max_vacuum_mmh2o * config.source_leak_conductance);
        assert!((state.source_mmh2o - expected).abs() < 1e-6);
        assert!(state.arm_mmh2o.iter().all(|p| p.abs() < 1e-6));
    }

    #[test]
    fn sealed_arm_holds_near_source_pressure_and_open_arm_leaks() {
        let config = VacuumConfig::default();
        let open_1 = [true, false, false, true];
        let mut sealed = VacuumPlantState::at_rest(&config);
        settle(
            &mut sealed,
            &config,
            open_1,
            [config.sealed_cup_conductance, config.open_cup_conductance],
        );
        let mut leaking = VacuumPlantState::at_rest(&config);
        settle(
            &mut leaking,
            &config,
            open_1,
            [config.open_cup_conductance; 2],
        );
        assert!(sealed.arm_mmh2o[0] > 0.9 * config.source_max_vacuum_mmh2o);
        assert!(leaking.arm_mmh2o[0] < 0.5 * sealed.arm_mmh2o[0]);
        assert!(leaking.source_mmh2o < 0.6 * config.source_max_vacuum_mmh2o);
        // Known answer of the closed form for the leaking arm.
        let g_in = config.inlet_conductance;
        let g_out = config.open_cup_conductance;
        let admittance = config.source_leak_conductance + g_in * g_out / (g_in + g_out);
        let source = 2500.0 * 360.0 / (360.0 + 2500.0 * admittance);
        assert!((leaking.source_mmh2o - source).abs() < 1e-6);
        assert!((leaking.arm_mmh2o[0] - source * g_in / (g_in + g_out)).abs() < 1e-6);
    }

    #[test]
    fn a_second_open_unsealed_arm_lowers_the_first_arms_vacuum() {
        let config = VacuumConfig::default();
        let cups = [config.sealed_cup_conductance, config.open_cup_conductance];
        let mut alone = VacuumPlantState::at_rest(&config);
        settle(&mut alone, &config, [true, false, false, true], cups);
        let mut both = VacuumPlantState::at_rest(&config);
        settle(&mut both, &config, [true, false, true, false], cups);
        assert!(both.arm_mmh2o[0] < 0.6 * alone.arm_mmh2o[0]);
        assert!(both.holding_force_n(&config, 0) < alone.holding_force_n(&config, 0));
    }

    #[test]
    fn valves_take_their_travel_time_and_pressure_lags() {
        let config = VacuumConfig::default();
        let mut state = VacuumPlantState::at_rest(&config);
        let cups = [config.sealed_cup_conductance, config.open_cup_conductance];
        let dt = 0.01;
        let steps = (config.valve_travel_time_s / 2.0 / dt).round() as usize;
        for _ in 0..steps {
            state.step(&config, dt, [true, false, false, true], cups);
        }
        assert!((state.valve_opening[0] - 0.5).abs() < 1e-9);
        assert!((state.valve_opening[1] - 0.5).abs() < 1e-9);
        assert!(state.arm_mmh2o[0] < 0.9 * config.source_max_vacuum_mmh2o);
        settle(&mut state, &config, [true, false, false, true], cups);
        assert_eq!(state.valve_opening, [1.0, 0.0, 0.0, 1.0]);
    }
}
