//! [`VacuumNodeConfig`]: the settings of the vacuum node, and [`VacuumNodeError`] when they are
//! invalid.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::policy::PolicyKind;
use crate::pressure::{PressureConfig, PressureConfigError};
use crate::replan::{PlannerConfig, PlannerConfigError};

/// Settings of the node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VacuumNodeConfig {
    /// Coordination policy.
    pub policy: PolicyKind,
    /// Attachment inference thresholds.
    pub pressure: PressureConfig,
    /// Assignment and re-planning.
    pub planner: PlannerConfig,
    /// Arms that take part, indexed by [`ArmId::index`](harvest_robot_model::ArmId::index) (single-arm operation: `[true,
    /// false]`). A disabled arm gets no apple and its valve stays closed.
    pub arms_enabled: [bool; 2],
    /// A dispatched target that its arm has not taken up after this long is given up as a
    /// failed attempt, s (default 3 s: longer than the arm's 2 s target age limit, so the arm
    /// has dropped it by then).
    pub dispatch_timeout_s: f64,
    /// Radius of the give-up list, m (default 0.05 m: below the 7-8 cm between the centres of
    /// two touching apples, above the 3 cm identity match of the planner). A detection within
    /// it of a spot where `planner.max_attempts` attempts were made is ignored, so an apple
    /// that perception re-identifies as new after each attempt, or that the robot wrongly
    /// believes harvested, is not tried forever.
    pub give_up_radius_m: f64,
    /// Margin around an apple held in a cup, m (default 0.03 m: the 1.5 cm from cup to apple
    /// surface within which the cup seals, section 2.2, plus the +-1.5 cm localization error
    /// the end-effector tolerates). A detection whose centre lies within its own radius plus
    /// this margin of the end-effector (`ArmState::end_effector_in_robot_m`) of an arm that
    /// holds an apple, retracts or releases is the apple in that cup seen again, not a tree
    /// apple, and is left out of the assignment (counted as `held` in the re-plan summary).
    /// Two touching apples of radius r lie at least ~2.2 r apart measured from the cup, so the
    /// default (r + 3 cm, 7 cm for r = 4 cm) does not hide a neighbour.
    pub held_margin_m: f64,
    /// How long an arm may report its dispatched target as waiting (refused for the moment)
    /// before the apple is handed elsewhere, s (default 0.25 s: the other arm's swept path
    /// rarely clears sooner than its next phase, and a shorter wait would bounce apples between
    /// the arms at every perception period).
    pub waiting_patience_s: f64,
    /// An apple withdrawn from an arm is not dispatched to that arm again for this long, s
    /// (default 1 s, about one phase of the other arm, whose path was in the way).
    pub withdrawal_backoff_s: f64,
    /// A fruit that slipped off the cup (its seal lost with the valve open) after the arm line
    /// held at least this vacuum while sealed, mmH2O, has a stem the cup cannot break: its
    /// spot goes on the give-up list at once instead of being tried again (default 2000
    /// mmH2O, 80 % of the 2500 mmH2O source: about 38 N of the 47 N rated force, sections
    /// 2.2-2.3; a slip with the vacuum sagged, e.g. while the other arm's cup was open, is
    /// still retried). 0 turns it off (every failed apple gets `planner.max_attempts`).
    #[serde(default = "default_slip_give_up_vacuum_mmh2o")]
    pub slip_give_up_vacuum_mmh2o: f32,
}

fn default_slip_give_up_vacuum_mmh2o() -> f32 {
    2000.0
}

impl Default for VacuumNodeConfig {
    fn default() -> Self {
        Self {
            policy: PolicyKind::V2024,
            pressure: PressureConfig::default(),
            planner: PlannerConfig::default(),
            arms_enabled: [true, true],
            dispatch_timeout_s: 3.0,
            give_up_radius_m: 0.05,
            held_margin_m: 0.03,
            waiting_patience_s: 0.25,
            withdrawal_backoff_s: 1.0,
            slip_give_up_vacuum_mmh2o: default_slip_give_up_vacuum_mmh2o(),
        }
    }
}

/// Why a [`VacuumNode`](super::VacuumNode) could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VacuumNodeError {
    /// Invalid pressure thresholds.
    #[error("vacuum node: {0}")]
    Pressure(#[from] PressureConfigError),
    /// Invalid planner settings.
    #[error("vacuum node: {0}")]
    Planner(#[from] PlannerConfigError),
    /// `dispatch_timeout_s` is not a positive number of seconds.
    #[error("vacuum node config `dispatch_timeout_s` = {0}: must be finite and > 0")]
    DispatchTimeout(f64),
    /// `give_up_radius_m` is not a positive distance.
    #[error("vacuum node config `give_up_radius_m` = {0}: must be finite and > 0")]
    GiveUpRadius(f64),
    /// `held_margin_m` is not a non-negative distance.
    #[error("vacuum node config `held_margin_m` = {0}: must be finite and >= 0")]
    HeldMargin(f64),
    /// `waiting_patience_s` is not a non-negative number of seconds.
    #[error("vacuum node config `waiting_patience_s` = {0}: must be finite and >= 0")]
    WaitingPatience(f64),
    /// `withdrawal_backoff_s` is not a non-negative number of seconds.
    #[error("vacuum node config `withdrawal_backoff_s` = {0}: must be finite and >= 0")]
    WithdrawalBackoff(f64),
    /// `slip_give_up_vacuum_mmh2o` is not a non-negative vacuum.
    #[error("vacuum node config `slip_give_up_vacuum_mmh2o` = {0}: must be finite and >= 0")]
    SlipGiveUpVacuum(f32),
}
