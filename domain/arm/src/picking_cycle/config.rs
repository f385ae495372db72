//! [`CycleConfig`]: the tunables of the picking cycle, and their check.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::controller::{GainsError, TrackingGains};
use harvest_robot_model::clearance::DEFAULT_CLEARANCE_M;
use harvest_robot_model::params::ParamsError;

/// Tunables of the picking cycle; the defaults are documented choices consistent with the
/// Fig. 12 cycle-time analysis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CycleConfig {
    /// Fraction of the joint and end-effector speed limits used (0.6 in the field, sec. 4.2).
    pub speed_fraction: f64,
    /// Distance short of the apple along -x of the intermediate approach waypoint, m (0: none).
    pub approach_standoff_m: f64,
    /// End-effector distance to a motion goal that counts as arrived, m.
    pub arrival_tolerance_m: f64,
    /// Twist error that counts as arrived, rad.
    pub twist_tolerance_rad: f64,
    /// Time allowed after a trajectory ends to settle within tolerance, s.
    pub settle_timeout_s: f64,
    /// Time allowed for the valve to report open after the request, s.
    pub valve_grant_timeout_s: f64,
    /// Time allowed for the pressure feedback to confirm the attachment once the valve is
    /// open, s.
    pub attach_timeout_s: f64,
    /// End-effector twist applied to detach the apple before the pull, rad. [alacs sec. 2]
    /// rotates the end-effector by an angle it does not give; the default is a quarter turn:
    /// twisting relieves the stem (the simulator's `stems.twist_relief`, full at a quarter turn),
    /// and on the rows an eighth of a turn left stems within the cup's force slipping
    /// (docs/evaluation.md, `harvest eval row`).
    pub detach_twist_rad: f64,
    /// Time the valve stays closed at the drop-off for the apple to fall, s.
    pub release_dwell_s: f64,
    /// Oldest detection accepted as a target, s.
    pub max_target_age_s: f64,
    /// Oldest joint feedback accepted, s.
    pub max_feedback_age_s: f64,
    /// Minimum tube-axis distance to the other arm over both swept paths, m.
    pub clearance_m: f64,
    /// Control period assumed on the first step, s (200 Hz, section 2.2).
    pub nominal_period_s: f64,
    /// Longest time between two steps, in nominal periods, before the step brakes the arm as
    /// after a feedback outage (the control loop missed its deadline: the servos ran that long
    /// on the last set-point). Default 3 (15 ms at 200 Hz); must be > 1.
    #[serde(default = "default_max_tick_gap_periods")]
    pub max_tick_gap_periods: f64,
    /// Tracking controller gains.
    pub gains: TrackingGains,
}

fn default_max_tick_gap_periods() -> f64 {
    3.0
}

impl Default for CycleConfig {
    fn default() -> Self {
        Self {
            speed_fraction: 0.6,
            approach_standoff_m: 0.05,
            arrival_tolerance_m: 0.005,
            twist_tolerance_rad: 0.05,
            settle_timeout_s: 1.0,
            valve_grant_timeout_s: 3.0,
            attach_timeout_s: 1.0,
            detach_twist_rad: std::f64::consts::FRAC_PI_2,
            release_dwell_s: 0.15,
            max_target_age_s: 2.0,
            max_feedback_age_s: 0.05,
            clearance_m: DEFAULT_CLEARANCE_M,
            nominal_period_s: 0.005,
            max_tick_gap_periods: default_max_tick_gap_periods(),
            gains: TrackingGains::default(),
        }
    }
}

/// Why a [`PickingCycle`](super::PickingCycle) could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CycleConfigError {
    /// A configuration value is out of range.
    #[error("cycle config `{field}` = {value} is invalid: {expected}")]
    Invalid {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What was expected.
        expected: &'static str,
    },
    /// The arm parameters are invalid.
    #[error("arm parameters: {0}")]
    Params(#[from] ParamsError),
    /// The gains are invalid.
    #[error("gains: {0}")]
    Gains(#[from] GainsError),
}

impl CycleConfig {
    /// Checks every value: speed fraction in (0, 1], durations and tolerances > 0, standoff
    /// and clearance >= 0, gains valid.
    pub fn validate(&self) -> Result<(), CycleConfigError> {
        let positive = [
            ("arrival_tolerance_m", self.arrival_tolerance_m),
            ("twist_tolerance_rad", self.twist_tolerance_rad),
            ("settle_timeout_s", self.settle_timeout_s),
            ("valve_grant_timeout_s", self.valve_grant_timeout_s),
            ("attach_timeout_s", self.attach_timeout_s),
            ("release_dwell_s", self.release_dwell_s),
            ("max_target_age_s", self.max_target_age_s),
            ("max_feedback_age_s", self.max_feedback_age_s),
            ("nominal_period_s", self.nominal_period_s),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(CycleConfigError::Invalid {
                    field,
                    value,
                    expected: "finite and > 0",
                });
            }
        }
        let non_negative = [
            ("approach_standoff_m", self.approach_standoff_m),
            ("clearance_m", self.clearance_m),
        ];
        for (field, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(CycleConfigError::Invalid {
                    field,
                    value,
                    expected: "finite and >= 0",
                });
            }
        }
        if !(self.speed_fraction > 0.0 && self.speed_fraction <= 1.0) {
            return Err(CycleConfigError::Invalid {
                field: "speed_fraction",
                value: self.speed_fraction,
                expected: "in (0, 1]",
            });
        }
        if !(self.max_tick_gap_periods.is_finite() && self.max_tick_gap_periods > 1.0) {
            return Err(CycleConfigError::Invalid {
                field: "max_tick_gap_periods",
                value: self.max_tick_gap_periods,
                expected: "finite and > 1",
            });
        }
        if !self.detach_twist_rad.is_finite() {
            return Err(CycleConfigError::Invalid {
                field: "detach_twist_rad",
                value: self.detach_twist_rad,
                expected: "finite",
            });
        }
        self.gains.validate()?;
        Ok(())
    }
}
