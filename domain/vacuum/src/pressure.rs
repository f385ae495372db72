//! Attachment inference from the three pressure sensors of the valve system ([dual-arm sec.
//! 2.3, Fig. 3]: one sensor inside arm 1, one inside arm 2, one at the vacuum source;
//! source up to 2500 mmH2O of vacuum at 360 m^3/h).
//!
//! All pressures are *vacuum* in mmH2O below atmosphere (positive = suction), the convention
//! of the valve board driver.
//!
//! Physics used. With an arm's source valve open and nothing on the cup, air streams through
//! the cup and the tube, and the pressure drop along that path leaves the arm sensor below the
//! source: the cup and the inlet form a divider of two conductances, ratio
//! `g_inlet / (g_inlet + g_cup)` ([`ValveLineModel`]; 0.625 with a bare cup and 0.71 with a leaf
//! under it for the nominal valve box). When an apple seals the cup the flow stops and the arm
//! pressure climbs to the source pressure (0.99). With the valve closed the tube is vented and
//! reads about zero. Comparing the arm reading to the *source* reading (a ratio) rather than to
//! a fixed level keeps the inference valid when the source sags because the other arm is open
//! to the atmosphere. The ratio thresholds are derived from the line model
//! ([`PressureConfig::for_line`]), the one place where they meet the valve box's physics.
//!
//! States of one arm (see [`AttachmentState`]):
//!
//! ```text
//!            valve opens                  ratio >= on and vacuum >= on_min, held debounce
//!   Closed ─────────────► OpenToAtmosphere ─────────────────────────────────────► Sealed
//!     ▲                         │  no seal attach_timeout after the valve opened       │
//!     │                         ▼                                                      │ ratio < off or
//!     │                   AttachFailed                                     Dropped ◄───┘ vacuum < off_min,
//!     └──────── valve closes (from any state) ───────────────────────────────────────    held debounce
//! ```
//!
//! The failure states latch until the valve closes; the failure-aware policy closes it in the
//! same control period (eq. 11, first two clauses).

use harvest_robot_model::ArmId;
use harvest_robot_model::FailureKind;
use serde::{Deserialize, Serialize};
use std::fmt;
use thiserror::Error;
use tracing::{debug, trace};

/// The valve line as the linear-conductance model of the valve box sees it (the model the
/// simulator implements, `harvest_sim` `physics::vacuum`): with the inlet gate fully open and
/// the vent shut, air flows from the cup through the tube to the source, and the arm sensor reads
/// `g_inlet / (g_inlet + g_cup)` of the source vacuum (a divider of two conductances in series).
/// Conductances in m^3/h of air per mmH2O; only their ratios matter here.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ValveLineModel {
    /// Arm tube to source through the fully open inlet gate (valve 1 or 3).
    pub inlet_conductance: f64,
    /// End-effector open to the air (nothing on the cup).
    pub open_cup_conductance: f64,
    /// End-effector on a fruit with a leaf between them (no seal).
    pub leaf_blocked_cup_conductance: f64,
    /// End-effector sealed on a fruit (residual leak through the soft lip).
    pub sealed_cup_conductance: f64,
}

impl ValveLineModel {
    /// The nominal valve box: a tube and gate that pass 0.5 m^3/h per mmH2O, a bare cup 0.3,
    /// a cup held off the fruit by a leaf 0.2, a sealed cup 0.005 (1 % of the inlet). With the
    /// 2500 mmH2O / 360 m^3/h source (section 2.3) an open cup then draws about 110 m^3/h at
    /// 1 in 3 of the source's free flow, and a sealed cup holds 99 % of the source vacuum. The
    /// simulator's default `VacuumConfig` uses these values (the evaluation checks it).
    pub const NOMINAL: ValveLineModel = ValveLineModel {
        inlet_conductance: 0.5,
        open_cup_conductance: 0.3,
        leaf_blocked_cup_conductance: 0.2,
        sealed_cup_conductance: 0.005,
    };

    /// Arm vacuum over source vacuum with the inlet open and a cup of conductance `cup_conductance`.
    pub fn open_valve_ratio(&self, cup_conductance: f64) -> f64 {
        self.inlet_conductance / (self.inlet_conductance + cup_conductance)
    }

    /// The highest ratio an unsealed cup reads (open to the air or blocked by a leaf).
    pub fn unsealed_ratio(&self) -> f64 {
        self.open_valve_ratio(self.open_cup_conductance)
            .max(self.open_valve_ratio(self.leaf_blocked_cup_conductance))
    }

    /// The ratio a sealed cup reads.
    pub fn sealed_ratio(&self) -> f64 {
        self.open_valve_ratio(self.sealed_cup_conductance)
    }

    /// The ratio thresholds `(seal_ratio_on, seal_ratio_off)` this line calls for. With `u`
    /// the highest unsealed ratio and `s` the sealed one, the gap `g = s - u` is split in
    /// quarters: `on = u + g / 2` (a seal is declared halfway between a leaf-blocked cup and a
    /// sealed one, equal margins against both), `off = u + g / 4` (a lost seal is declared once
    /// the ratio has fallen a quarter of the gap below `on`; `off` stays above every unsealed
    /// reading, so an apple that slipped off a cup still open is always detected).
    pub fn ratio_thresholds(&self) -> Result<(f32, f32), PressureConfigError> {
        let conductances = [
            ("inlet_conductance", self.inlet_conductance),
            ("open_cup_conductance", self.open_cup_conductance),
            (
                "leaf_blocked_cup_conductance",
                self.leaf_blocked_cup_conductance,
            ),
            ("sealed_cup_conductance", self.sealed_cup_conductance),
        ];
        for (key, value) in conductances {
            if !(value.is_finite() && value > 0.0) {
                return Err(PressureConfigError::BadConductance { key, value });
            }
        }
        let (u, s) = (self.unsealed_ratio(), self.sealed_ratio());
        if s <= u {
            return Err(PressureConfigError::SealIndistinct {
                sealed: s,
                unsealed: u,
            });
        }
        let gap = s - u;
        Ok(((u + gap / 2.0) as f32, (u + gap / 4.0) as f32))
    }
}

impl Default for ValveLineModel {
    fn default() -> Self {
        ValveLineModel::NOMINAL
    }
}

/// Thresholds of the attachment inference. Defaults are documented on [`Default`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PressureConfig {
    /// Rising threshold on `arm_vacuum / source_vacuum`: at or above it (with
    /// `seal_on_min_vacuum_mmh2o`) the cup is considered sealed.
    pub seal_ratio_on: f32,
    /// Falling threshold on the same ratio: below it a sealed cup is considered leaking. The
    /// band between `seal_ratio_off` and `seal_ratio_on` is the hysteresis.
    pub seal_ratio_off: f32,
    /// Minimum arm vacuum, mmH2O, to declare a seal (absolute rising threshold).
    pub seal_on_min_vacuum_mmh2o: f32,
    /// Arm vacuum, mmH2O, below which a sealed apple is considered lost whatever the ratio
    /// (absolute falling threshold; too little suction to hold an apple).
    pub seal_off_min_vacuum_mmh2o: f32,
    /// Source vacuum, mmH2O, below which the ratio is not evaluated (vacuum machine off or
    /// blocked); [`AttachmentInference::source_ok`] reports it.
    pub source_min_vacuum_mmh2o: f32,
    /// A seal or a leak must hold continuously this long before the state changes, ns.
    pub debounce_ns: u64,
    /// With the valve open and no seal this long after it opened, the attachment has failed,
    /// ns. It is the "short wait" of the workflow (eq. 8, third clause) and matches the attach
    /// phase time of the cycle model.
    pub attach_timeout_ns: u64,
}

impl Default for PressureConfig {
    /// - `seal_ratio_on` / `seal_ratio_off`: derived from [`ValveLineModel::NOMINAL`] by
    ///   [`ValveLineModel::ratio_thresholds`] (0.852 / 0.783): a sealed cup has almost no flow
    ///   and reads 0.99 of the source, a bare cup 0.625 and a leaf-blocked one 0.714. The
    ///   thresholds are not free numbers: they must separate those levels of the valve box
    ///   the robot (or the simulator) actually has.
    /// - `seal_on_min_vacuum_mmh2o` 800 / `seal_off_min_vacuum_mmh2o` 500: the 47 N average
    ///   suction force at about 2500 mmH2O (sections 2.2, 2.3) implies an effective cup area of
    ///   about 19 cm^2, so 800 mmH2O still pulls about 15 N and 500 mmH2O about 9 N, three to
    ///   four times the weight of a 250 g apple; below that the apple is not held reliably
    ///   through the arm's accelerations.
    /// - `source_min_vacuum_mmh2o` 300: far below any working level of the source; below it the
    ///   machine is off or clogged and a ratio means nothing.
    /// - `debounce_ns` 20 ms: four samples at the 200 Hz control rate (section 2.2).
    /// - `attach_timeout_ns` 250 ms: the attach phase time derived from Fig. 12 (see POLICY.md).
    fn default() -> Self {
        PressureConfig::for_line(&ValveLineModel::NOMINAL)
    }
}

impl PressureConfig {
    /// The default thresholds with the ratio thresholds of `line` (see
    /// [`ValveLineModel::ratio_thresholds`]); a line model that cannot separate a seal from an
    /// open cup falls back to the nominal line's thresholds, which [`PressureConfig::validate`]
    /// then accepts. Use [`PressureConfig::try_for_line`] to see that error.
    pub fn for_line(line: &ValveLineModel) -> Self {
        Self::try_for_line(line).unwrap_or_else(|_| Self::with_ratios(NOMINAL_RATIOS))
    }

    /// The default thresholds with the ratio thresholds of `line`.
    pub fn try_for_line(line: &ValveLineModel) -> Result<Self, PressureConfigError> {
        Ok(Self::with_ratios(line.ratio_thresholds()?))
    }

    fn with_ratios((seal_ratio_on, seal_ratio_off): (f32, f32)) -> Self {
        PressureConfig {
            seal_ratio_on,
            seal_ratio_off,
            seal_on_min_vacuum_mmh2o: 800.0,
            seal_off_min_vacuum_mmh2o: 500.0,
            source_min_vacuum_mmh2o: 300.0,
            debounce_ns: 20_000_000,
            attach_timeout_ns: 250_000_000,
        }
    }
}

/// `(seal_ratio_on, seal_ratio_off)` of [`ValveLineModel::NOMINAL`], precomputed for the
/// fallback of [`PressureConfig::for_line`] (checked against the derivation by a test).
const NOMINAL_RATIOS: (f32, f32) = (0.852_192_34, 0.783_239_07);

/// A [`PressureConfig`] value that cannot work.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PressureConfigError {
    /// A conductance of the valve line model is not a positive number.
    #[error("valve line model key `{key}` = {value}: must be finite and > 0")]
    BadConductance {
        /// The offending key.
        key: &'static str,
        /// Its value.
        value: f64,
    },
    /// The valve line model gives a sealed cup no higher ratio than an unsealed one, so no
    /// threshold can tell them apart.
    #[error(
        "valve line model: a sealed cup reads {sealed:.3} of the source, not above an unsealed \
         cup's {unsealed:.3}"
    )]
    SealIndistinct {
        /// Ratio of a sealed cup.
        sealed: f64,
        /// Highest ratio of an unsealed cup.
        unsealed: f64,
    },
    /// A ratio threshold is outside (0, 1].
    #[error("pressure config key `{key}` = {value}: a ratio threshold must lie in (0, 1]")]
    RatioOutOfRange {
        /// The offending key.
        key: &'static str,
        /// Its value.
        value: f32,
    },
    /// The hysteresis band is empty or inverted.
    #[error(
        "pressure config: `{off_key}` = {off} must be below `{on_key}` = {on} (hysteresis band)"
    )]
    InvertedHysteresis {
        /// Key of the falling threshold.
        off_key: &'static str,
        /// Its value.
        off: f32,
        /// Key of the rising threshold.
        on_key: &'static str,
        /// Its value.
        on: f32,
    },
    /// A vacuum threshold is negative or not finite.
    #[error("pressure config key `{key}` = {value} mmH2O: must be finite and positive")]
    BadVacuum {
        /// The offending key.
        key: &'static str,
        /// Its value.
        value: f32,
    },
    /// The debounce time is not shorter than the attach timeout, so a seal could never be
    /// confirmed before the attempt is declared failed.
    #[error(
        "pressure config: `debounce_ns` = {debounce_ns} must be below `attach_timeout_ns` = {attach_timeout_ns}"
    )]
    DebounceTooLong {
        /// The debounce time, ns.
        debounce_ns: u64,
        /// The attach timeout, ns.
        attach_timeout_ns: u64,
    },
}

impl PressureConfig {
    /// Check the thresholds for consistency.
    pub fn validate(&self) -> Result<(), PressureConfigError> {
        for (key, value) in [
            ("seal_ratio_on", self.seal_ratio_on),
            ("seal_ratio_off", self.seal_ratio_off),
        ] {
            if !(value > 0.0 && value <= 1.0) {
                return Err(PressureConfigError::RatioOutOfRange { key, value });
            }
        }
        for (key, value) in [
            ("seal_on_min_vacuum_mmh2o", self.seal_on_min_vacuum_mmh2o),
            ("seal_off_min_vacuum_mmh2o", self.seal_off_min_vacuum_mmh2o),
            ("source_min_vacuum_mmh2o", self.source_min_vacuum_mmh2o),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(PressureConfigError::BadVacuum { key, value });
            }
        }
        if self.seal_ratio_off >= self.seal_ratio_on {
            return Err(PressureConfigError::InvertedHysteresis {
                off_key: "seal_ratio_off",
                off: self.seal_ratio_off,
                on_key: "seal_ratio_on",
                on: self.seal_ratio_on,
            });
        }
        if self.seal_off_min_vacuum_mmh2o >= self.seal_on_min_vacuum_mmh2o {
            return Err(PressureConfigError::InvertedHysteresis {
                off_key: "seal_off_min_vacuum_mmh2o",
                off: self.seal_off_min_vacuum_mmh2o,
                on_key: "seal_on_min_vacuum_mmh2o",
                on: self.seal_on_min_vacuum_mmh2o,
            });
        }
        if self.debounce_ns >= self.attach_timeout_ns {
            return Err(PressureConfigError::DebounceTooLong {
                debounce_ns: self.debounce_ns,
                attach_timeout_ns: self.attach_timeout_ns,
            });
        }
        Ok(())
    }
}

/// What the pressure sensors say about one arm's end-effector.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum AttachmentState {
    /// The source valve is closed: the tube is vented, nothing can be held.
    Closed,
    /// The valve is open and air streams in through the cup: no seal (yet).
    OpenToAtmosphere,
    /// The valve is open and an apple seals the cup (`Apple_Attached_i` of eq. 7-12).
    Sealed,
    /// The valve has been open for the attach timeout without a seal. Latches until the valve
    /// closes.
    AttachFailed,
    /// A seal was lost with the valve still open (apple dropped or leaking). Latches until the
    /// valve closes.
    Dropped,
}

impl AttachmentState {
    /// True when an apple seals the cup (`Apple_Attached_i`).
    pub const fn is_sealed(self) -> bool {
        matches!(self, AttachmentState::Sealed)
    }

    /// The failure this state reports, if any.
    pub const fn failure_kind(self) -> Option<FailureKind> {
        match self {
            AttachmentState::AttachFailed => Some(FailureKind::AttachFailed),
            AttachmentState::Dropped => Some(FailureKind::Dropped),
            _ => None,
        }
    }
}

impl fmt::Display for AttachmentState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            AttachmentState::Closed => "closed",
            AttachmentState::OpenToAtmosphere => "open to atmosphere",
            AttachmentState::Sealed => "sealed",
            AttachmentState::AttachFailed => "attach failed",
            AttachmentState::Dropped => "dropped",
        };
        f.write_str(name)
    }
}

/// A change of one arm's inferred state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AttachmentChange {
    /// Stamp of the sample that caused the change, ns.
    pub stamp_ns: u64,
    /// Which arm.
    pub arm: ArmId,
    /// State before.
    pub from: AttachmentState,
    /// State after.
    pub to: AttachmentState,
}

impl AttachmentChange {
    /// The failure detected by this change, if it entered a failure state.
    pub const fn failure(&self) -> Option<FailureKind> {
        self.to.failure_kind()
    }
}

/// One reading of the three sensors, taken together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressureSample {
    /// Time of validity of the readings, ns.
    pub stamp_ns: u64,
    /// Vacuum inside arm 1 and arm 2 (indexed by [`ArmId::index`]), mmH2O.
    pub arm_vacuum_mmh2o: [f32; 2],
    /// Vacuum at the source, mmH2O.
    pub source_vacuum_mmh2o: f32,
}

/// Which sensor a bad reading came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PressureSensor {
    /// The sensor inside an arm.
    Arm(ArmId),
    /// The sensor at the vacuum source.
    Source,
}

impl fmt::Display for PressureSensor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PressureSensor::Arm(arm) => write!(f, "sensor inside {arm}"),
            PressureSensor::Source => f.write_str("source sensor"),
        }
    }
}

/// A sample the inference refused; the state is left unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum PressureSampleError {
    /// A reading is NaN or infinite.
    #[error("pressure sample at {stamp_ns} ns: {sensor} read {value} mmH2O (not finite)")]
    NonFinite {
        /// Stamp of the sample, ns.
        stamp_ns: u64,
        /// The sensor.
        sensor: PressureSensor,
        /// The reading.
        value: f32,
    },
    /// The stamp is older than the previous sample's.
    #[error("pressure sample at {stamp_ns} ns is older than the previous one at {previous_ns} ns")]
    StampWentBack {
        /// Stamp of the refused sample, ns.
        stamp_ns: u64,
        /// Stamp of the last accepted sample, ns.
        previous_ns: u64,
    },
}

/// The inference for one arm: a debounced, hysteretic state machine over the arm/source
/// vacuum ratio.
#[derive(Debug, Clone)]
pub struct AttachmentEstimator {
    arm: ArmId,
    config: PressureConfig,
    state: AttachmentState,
    /// When the valve was first seen open in the current opening, ns.
    opened_at_ns: u64,
    /// Since when the candidate condition (seal when open, leak when sealed) holds, ns.
    candidate_since_ns: Option<u64>,
}

impl AttachmentEstimator {
    /// A new estimator for `arm`, starting closed. `config` should have passed
    /// [`PressureConfig::validate`].
    pub fn new(arm: ArmId, config: PressureConfig) -> Self {
        AttachmentEstimator {
            arm,
            config,
            state: AttachmentState::Closed,
            opened_at_ns: 0,
            candidate_since_ns: None,
        }
    }

    /// The current inferred state.
    pub fn state(&self) -> AttachmentState {
        self.state
    }

    /// Feed one sample: the commanded state of this arm's source valve and the arm and source
    /// vacuum at `stamp_ns`. Returns the state change, if any. Readings must be finite (checked
    /// by [`AttachmentInference::update`]).
    pub fn update(
        &mut self,
        stamp_ns: u64,
        valve_open: bool,
        arm_vacuum_mmh2o: f32,
        source_vacuum_mmh2o: f32,
    ) -> Option<AttachmentChange> {
        let from = self.state;
        let to = self.next_state(stamp_ns, valve_open, arm_vacuum_mmh2o, source_vacuum_mmh2o);
        trace!(
            arm = %self.arm, stamp_ns, valve_open, arm_vacuum_mmh2o, source_vacuum_mmh2o,
            state = %to, "attachment inference sample"
        );
        if to == from {
            return None;
        }
        self.state = to;
        self.candidate_since_ns = None;
        if to == AttachmentState::OpenToAtmosphere {
            self.opened_at_ns = stamp_ns;
        }
        debug!(arm = %self.arm, stamp_ns, %from, %to, "attachment state changed");
        Some(AttachmentChange {
            stamp_ns,
            arm: self.arm,
            from,
            to,
        })
    }

    fn next_state(
        &mut self,
        stamp_ns: u64,
        valve_open: bool,
        arm_vacuum_mmh2o: f32,
        source_vacuum_mmh2o: f32,
    ) -> AttachmentState {
        let c = self.config;
        if !valve_open {
            return AttachmentState::Closed;
        }
        let source_ok = source_vacuum_mmh2o >= c.source_min_vacuum_mmh2o;
        match self.state {
            AttachmentState::Closed => AttachmentState::OpenToAtmosphere,
            AttachmentState::OpenToAtmosphere => {
                let seal_seen = source_ok
                    && arm_vacuum_mmh2o >= c.seal_on_min_vacuum_mmh2o
                    && arm_vacuum_mmh2o >= c.seal_ratio_on * source_vacuum_mmh2o;
                if self.debounced(stamp_ns, seal_seen) {
                    AttachmentState::Sealed
                } else if stamp_ns.saturating_sub(self.opened_at_ns) >= c.attach_timeout_ns {
                    AttachmentState::AttachFailed
                } else {
                    AttachmentState::OpenToAtmosphere
                }
            }
            AttachmentState::Sealed => {
                let leak_seen = arm_vacuum_mmh2o < c.seal_off_min_vacuum_mmh2o
                    || (source_ok && arm_vacuum_mmh2o < c.seal_ratio_off * source_vacuum_mmh2o);
                if self.debounced(stamp_ns, leak_seen) {
                    AttachmentState::Dropped
                } else {
                    AttachmentState::Sealed
                }
            }
            latched @ (AttachmentState::AttachFailed | AttachmentState::Dropped) => latched,
        }
    }

    /// True once `condition` has held continuously for the debounce time.
    fn debounced(&mut self, stamp_ns: u64, condition: bool) -> bool {
        if !condition {
            self.candidate_since_ns = None;
            return false;
        }
        let since = *self.candidate_since_ns.get_or_insert(stamp_ns);
        stamp_ns.saturating_sub(since) >= self.config.debounce_ns
    }
}

/// The inference for both arms plus the source health, fed with whole samples.
#[derive(Debug, Clone)]
pub struct AttachmentInference {
    config: PressureConfig,
    estimators: [AttachmentEstimator; 2],
    last_stamp_ns: Option<u64>,
    source_ok: bool,
}

impl AttachmentInference {
    /// A new inference, both arms closed. `config` should have passed
    /// [`PressureConfig::validate`].
    pub fn new(config: PressureConfig) -> Self {
        AttachmentInference {
            config,
            estimators: ArmId::ALL.map(|arm| AttachmentEstimator::new(arm, config)),
            last_stamp_ns: None,
            source_ok: true,
        }
    }

    /// Feed one sample with the commanded source-valve state of each arm (indexed by
    /// [`ArmId::index`]). Returns each arm's state change, if any. A refused sample leaves the
    /// state unchanged.
    pub fn update(
        &mut self,
        sample: &PressureSample,
        valves_open: [bool; 2],
    ) -> Result<[Option<AttachmentChange>; 2], PressureSampleError> {
        let stamp_ns = sample.stamp_ns;
        if let Some(previous_ns) = self.last_stamp_ns
            && stamp_ns < previous_ns
        {
            return Err(PressureSampleError::StampWentBack {
                stamp_ns,
                previous_ns,
            });
        }
        for arm in ArmId::ALL {
            let value = sample.arm_vacuum_mmh2o[arm.index()];
            if !value.is_finite() {
                return Err(PressureSampleError::NonFinite {
                    stamp_ns,
                    sensor: PressureSensor::Arm(arm),
                    value,
                });
            }
        }
        if !sample.source_vacuum_mmh2o.is_finite() {
            return Err(PressureSampleError::NonFinite {
                stamp_ns,
                sensor: PressureSensor::Source,
                value: sample.source_vacuum_mmh2o,
            });
        }
        self.last_stamp_ns = Some(stamp_ns);
        self.source_ok = sample.source_vacuum_mmh2o >= self.config.source_min_vacuum_mmh2o;
        Ok(ArmId::ALL.map(|arm| {
            self.estimators[arm.index()].update(
                stamp_ns,
                valves_open[arm.index()],
                sample.arm_vacuum_mmh2o[arm.index()],
                sample.source_vacuum_mmh2o,
            )
        }))
    }

    /// The inferred state of `arm`.
    pub fn state(&self, arm: ArmId) -> AttachmentState {
        self.estimators[arm.index()].state()
    }

    /// Both arms' inferred states, indexed by [`ArmId::index`].
    pub fn states(&self) -> [AttachmentState; 2] {
        ArmId::ALL.map(|arm| self.state(arm))
    }

    /// False when the last sample's source vacuum was below `source_min_vacuum_mmh2o`.
    pub fn source_ok(&self) -> bool {
        self.source_ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    const PERIOD_NS: u64 = 5_000_000;
    const SOURCE: f32 = 2300.0;

    fn cfg() -> PressureConfig {
        PressureConfig::default()
    }

    /// Feeds `n` samples of constant readings to one estimator starting at `t0`, returns the
    /// changes and the next stamp.
    fn feed(
        est: &mut AttachmentEstimator,
        t0: u64,
        n: u64,
        open: bool,
        arm: f32,
        source: f32,
    ) -> (Vec<AttachmentChange>, u64) {
        let mut changes = Vec::new();
        let mut t = t0;
        for _ in 0..n {
            if let Some(c) = est.update(t, open, arm, source) {
                changes.push(c);
            }
            t += PERIOD_NS;
        }
        (changes, t)
    }

    #[test]
    fn thresholds_derive_from_the_valve_line_and_separate_its_levels() {
        let line = ValveLineModel::NOMINAL;
        // Known answers of the conductance divider: 0.5 / (0.5 + g_cup).
        assert!((line.open_valve_ratio(line.open_cup_conductance) - 0.625).abs() < 1e-12);
        assert!((line.unsealed_ratio() - 0.5 / 0.7).abs() < 1e-12);
        assert!((line.sealed_ratio() - 0.5 / 0.505).abs() < 1e-12);
        let (on, off) = line.ratio_thresholds().expect("nominal line");
        assert_eq!((on, off), NOMINAL_RATIOS, "precomputed fallback is stale");
        assert_eq!((cfg().seal_ratio_on, cfg().seal_ratio_off), (on, off));
        // Every unsealed level lies below `off`, the sealed level above `on`.
        let (on, off) = (f64::from(on), f64::from(off));
        assert!(line.unsealed_ratio() < off && off < on && on < line.sealed_ratio());
        // A cup that lost its apple (open to the air) is read as a drop: below `off`.
        assert!(line.open_valve_ratio(line.open_cup_conductance) < off);
        // A model that cannot tell a seal apart is refused, by name.
        let leaky = ValveLineModel {
            sealed_cup_conductance: 0.4,
            ..line
        };
        assert!(matches!(
            leaky.ratio_thresholds(),
            Err(PressureConfigError::SealIndistinct { .. })
        ));
        assert_eq!(PressureConfig::for_line(&leaky), cfg());
        let bad = ValveLineModel {
            inlet_conductance: f64::NAN,
            ..line
        };
        let err = PressureConfig::try_for_line(&bad).expect_err("NaN conductance");
        assert!(err.to_string().contains("inlet_conductance"), "{err}");
    }

    #[test]
    fn default_config_validates_and_bad_ones_are_named() {
        assert_eq!(cfg().validate(), Ok(()));
        let bad = PressureConfig {
            seal_ratio_off: 0.9,
            ..cfg()
        };
        assert!(matches!(
            bad.validate(),
            Err(PressureConfigError::InvertedHysteresis {
                off_key: "seal_ratio_off",
                ..
            })
        ));
        let bad = PressureConfig {
            seal_ratio_on: 1.5,
            ..cfg()
        };
        let msg = bad
            .validate()
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            msg.contains("seal_ratio_on") && msg.contains("1.5"),
            "{msg}"
        );
        let bad = PressureConfig {
            debounce_ns: 300_000_000,
            ..cfg()
        };
        assert!(matches!(
            bad.validate(),
            Err(PressureConfigError::DebounceTooLong { .. })
        ));
    }

    #[test]
    fn config_parses_from_toml_and_refuses_unknown_keys() {
        let text = "seal_ratio_on = 0.85\nseal_ratio_off = 0.55\nseal_on_min_vacuum_mmh2o = 900.0\n\
                    seal_off_min_vacuum_mmh2o = 400.0\nsource_min_vacuum_mmh2o = 250.0\n\
                    debounce_ns = 15000000\nattach_timeout_ns = 300000000\n";
        let parsed: PressureConfig = toml::from_str(text).expect("valid config");
        assert_eq!(parsed.seal_ratio_on, 0.85);
        assert_eq!(parsed.attach_timeout_ns, 300_000_000);
        assert_eq!(parsed.validate(), Ok(()));
        let unknown = format!("{text}seal_ratio = 0.7\n");
        let err = toml::from_str::<PressureConfig>(&unknown).expect_err("unknown key");
        assert!(err.to_string().contains("seal_ratio"), "{err}");
    }

    #[test]
    fn closed_valve_reads_closed_whatever_the_pressure() {
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (changes, _) = feed(&mut est, 0, 50, false, SOURCE, SOURCE);
        assert!(changes.is_empty());
        assert_eq!(est.state(), AttachmentState::Closed);
    }

    #[test]
    fn seal_is_declared_exactly_one_debounce_after_the_condition_starts() {
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        // Valve opens at t = 0 with an open cup (30 % of the source).
        let (changes, t) = feed(&mut est, 0, 4, true, 0.3 * SOURCE, SOURCE);
        assert_eq!(changes.len(), 1);
        assert_eq!(changes[0].to, AttachmentState::OpenToAtmosphere);
        // The apple seals at t = 20 ms: ratio 0.97 from then on.
        let (changes, _) = feed(&mut est, t, 10, true, 0.97 * SOURCE, SOURCE);
        assert_eq!(changes.len(), 1);
        assert_eq!(changes[0].to, AttachmentState::Sealed);
        assert_eq!(changes[0].stamp_ns, t + cfg().debounce_ns);
    }

    #[test]
    fn open_cup_fails_exactly_at_the_attach_timeout() {
        let mut est = AttachmentEstimator::new(ArmId::Arm2, cfg());
        let (changes, _) = feed(&mut est, 1_000, 100, true, 0.3 * SOURCE, SOURCE);
        assert_eq!(changes.len(), 2);
        assert_eq!(changes[1].to, AttachmentState::AttachFailed);
        assert_eq!(changes[1].failure(), Some(FailureKind::AttachFailed));
        assert_eq!(changes[1].stamp_ns, 1_000 + cfg().attach_timeout_ns);
        // Latched: a late seal does not revive the attempt; closing clears it.
        let (late, t) = feed(&mut est, 600_000_000, 20, true, 0.97 * SOURCE, SOURCE);
        assert!(late.is_empty());
        let (closed, _) = feed(&mut est, t, 1, false, 0.0, SOURCE);
        assert_eq!(closed[0].to, AttachmentState::Closed);
    }

    #[test]
    fn drop_needs_a_sustained_leak_and_short_dips_are_ignored() {
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (_, t) = feed(&mut est, 0, 10, true, 0.97 * SOURCE, SOURCE);
        assert_eq!(est.state(), AttachmentState::Sealed);
        // A 15 ms dip (3 samples) below the falling threshold: shorter than the debounce.
        let (dip, t) = feed(&mut est, t, 3, true, 0.4 * SOURCE, SOURCE);
        assert!(dip.is_empty());
        let (_, t) = feed(&mut est, t, 2, true, 0.97 * SOURCE, SOURCE);
        assert_eq!(est.state(), AttachmentState::Sealed);
        // A sustained leak.
        let (changes, _) = feed(&mut est, t, 10, true, 0.4 * SOURCE, SOURCE);
        assert_eq!(changes.len(), 1);
        assert_eq!(changes[0].to, AttachmentState::Dropped);
        assert_eq!(changes[0].stamp_ns, t + cfg().debounce_ns);
    }

    #[test]
    fn hysteresis_band_neither_seals_nor_drops() {
        // In the band (off..on) an unsealed arm stays unsealed...
        let band = 0.5 * (cfg().seal_ratio_off + cfg().seal_ratio_on);
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (_, _) = feed(&mut est, 0, 40, true, band * SOURCE, SOURCE);
        assert_eq!(est.state(), AttachmentState::OpenToAtmosphere);
        // ...and a sealed arm stays sealed.
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (_, t) = feed(&mut est, 0, 10, true, 0.97 * SOURCE, SOURCE);
        let (changes, _) = feed(&mut est, t, 1000, true, band * SOURCE, SOURCE);
        assert!(changes.is_empty());
        assert_eq!(est.state(), AttachmentState::Sealed);
    }

    #[test]
    fn sealed_arm_survives_a_source_sag_but_not_a_dead_source() {
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (_, t) = feed(&mut est, 0, 10, true, 0.97 * SOURCE, SOURCE);
        // Other arm opens to the atmosphere: source sags to 1200, the sealed arm follows it.
        let (changes, t) = feed(&mut est, t, 100, true, 1180.0, 1200.0);
        assert!(changes.is_empty());
        // Vacuum machine stops: everything decays to zero, the apple cannot be held.
        let (changes, _) = feed(&mut est, t, 10, true, 100.0, 120.0);
        assert_eq!(changes.len(), 1);
        assert_eq!(changes[0].to, AttachmentState::Dropped);
    }

    #[test]
    fn low_source_never_produces_a_seal() {
        // Both arms open to the atmosphere can drag the source very low: ratio ~1 at a level
        // too weak to hold an apple is not a seal.
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (changes, _) = feed(&mut est, 0, 100, true, 600.0, 620.0);
        let states: Vec<_> = changes.iter().map(|c| c.to).collect();
        assert_eq!(
            states,
            vec![
                AttachmentState::OpenToAtmosphere,
                AttachmentState::AttachFailed
            ]
        );
    }

    #[test]
    fn noisy_sealed_reading_gives_no_false_drop() {
        let mut rng = SmallRng::seed_from_u64(7);
        let mut est = AttachmentEstimator::new(ArmId::Arm1, cfg());
        let (_, mut t) = feed(&mut est, 0, 10, true, 0.97 * SOURCE, SOURCE);
        for _ in 0..20_000 {
            // +-60 mmH2O of noise on each sensor (a few percent of full scale).
            let arm = 0.95 * SOURCE + rng.random_range(-60.0..60.0);
            let source = SOURCE + rng.random_range(-60.0..60.0);
            assert_eq!(est.update(t, true, arm, source), None);
            t += PERIOD_NS;
        }
    }

    #[test]
    fn pair_inference_refuses_bad_samples_without_changing_state() {
        let mut inf = AttachmentInference::new(cfg());
        let good = PressureSample {
            stamp_ns: 10,
            arm_vacuum_mmh2o: [0.3 * SOURCE, 0.0],
            source_vacuum_mmh2o: SOURCE,
        };
        let changes = inf.update(&good, [true, false]).expect("good sample");
        assert_eq!(
            changes[0].map(|c| c.to),
            Some(AttachmentState::OpenToAtmosphere)
        );
        assert_eq!(changes[1], None);
        let nan = PressureSample {
            stamp_ns: 20,
            arm_vacuum_mmh2o: [f32::NAN, 0.0],
            ..good
        };
        let err = inf.update(&nan, [false, false]).expect_err("NaN refused");
        assert!(err.to_string().contains("arm 1"), "{err}");
        assert_eq!(inf.state(ArmId::Arm1), AttachmentState::OpenToAtmosphere);
        let old = PressureSample {
            stamp_ns: 5,
            ..good
        };
        assert!(matches!(
            inf.update(&old, [false, false]),
            Err(PressureSampleError::StampWentBack {
                previous_ns: 10,
                ..
            })
        ));
        let dead = PressureSample {
            stamp_ns: 30,
            arm_vacuum_mmh2o: [0.0, 0.0],
            source_vacuum_mmh2o: 50.0,
        };
        inf.update(&dead, [false, false]).expect("finite sample");
        assert!(!inf.source_ok());
        assert_eq!(inf.states(), [AttachmentState::Closed; 2]);
    }
}
