//! The simulated platform movement module ([dual-arm sec. 2]): two stepper stages, in-out
//! (toward the canopy) and up-down, behind an Arduino that takes targets and reports the
//! stages' positions at a steady rate.
//!
//! Dynamics per stage (position `x`, target `r`, both m from the stage's stop):
//!
//! `dx/dt = clamp((r - x) / tau, -v_max, v_max)`
//!
//! i.e. the stage cruises at its top speed `v_max` and ends with a first-order approach of time
//! constant `tau` (the controller's deceleration ramp); once within the encoder resolution it
//! stops exactly on the target and reports `in_motion = 0`. A stop command makes the current
//! position the target (steppers at a few cm/s stop within a step). Targets outside the travel
//! or not finite are refused: the stage keeps its previous target and the feedback says so.
//!
//! The paper gives no stroke, speed or feedback rate; the choices ([`PlatformDeviceConfig`]):
//! travel 0.50 m in-out and 0.80 m up-down ([`PlatformTravel::default`]); 0.05 m/s on both
//! stages (a lead-screw stepper stage carrying both arms and the vacuum system, moved between
//! harvesting positions, "slow" per the paper's discussion of lighter arms allowing faster
//! platform movement); `tau` = 0.2 s; 0.1 mm encoder resolution; feedback at 50 Hz (an Arduino
//! Uno reporting over serial). The stages start at their stops (homed at power-up).
//!
//! Moving the platform moves the robot in the simulated world: the physics thread turns the
//! stages' positions into the robot's offset in the row frame ([`crate::world_motion`]), so
//! the renderers, the physics and the arms' reach follow the stages.
//!
//! - [`PlatformStages`]: the two stages' state and dynamics (pure, steppable);
//! - [`PlatformDeviceServer`]: the stages behind the `hw/platform/*` channels, ticked by the
//!   sim process at the feedback rate;
//! - [`LocalPlatform`]: the stages as an in-process [`Platform`], advanced by the host clock.

use harvest_hw::error_kind::{DeviceError, ErrorKind};
use harvest_hw::platform::{Platform, PlatformAxis, PlatformPosition, PlatformTravel};
use harvest_ipc::catalogue::{HW_PLATFORM_COMMAND, HW_PLATFORM_FEEDBACK};
use harvest_ipc::payloads::PlatformStatus;
use harvest_ipc::payloads::{PlatformCommand, PlatformFeedback};
use harvest_ipc::{Context, MonotonicClock, Publisher, Subscriber};
use serde::{Deserialize, Serialize};
use std::time::{Duration, Instant};

/// Longest integration step of the stage dynamics, s.
const MAX_SUBSTEP_S: f64 = 0.005;

/// How the simulated platform behaves (choices documented in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlatformDeviceConfig {
    /// The stages' strokes.
    pub travel: PlatformTravel,
    /// Top speed `[in_out, up_down]`, m/s.
    pub max_speed_m_per_s: [f64; 2],
    /// Time constant `tau` of the final approach, s.
    pub time_constant_s: f64,
    /// The stages stop on the target once this close, m.
    pub encoder_resolution_m: f64,
    /// Position at power-up `[in_out, up_down]`, m.
    pub start_m: [f64; 2],
    /// Period of the position feedback, s.
    pub feedback_period_s: f64,
}

impl Default for PlatformDeviceConfig {
    fn default() -> Self {
        Self {
            travel: PlatformTravel::default(),
            max_speed_m_per_s: [0.05, 0.05],
            time_constant_s: 0.2,
            encoder_resolution_m: 1e-4,
            start_m: [0.0, 0.0],
            feedback_period_s: 0.02,
        }
    }
}

/// Why the simulated platform cannot run.
#[derive(Debug, thiserror::Error)]
pub enum PlatformDeviceError {
    /// A configuration value is unusable.
    #[error("platform device config: {field} = {value} is invalid ({rule})")]
    InvalidConfig {
        field: &'static str,
        value: f64,
        rule: &'static str,
    },
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(PlatformDeviceError);

impl PlatformDeviceConfig {
    /// Refuses non-finite or non-positive speeds, time constant, resolution and period, an
    /// empty travel, and a start outside it.
    pub fn validate(&self) -> Result<(), PlatformDeviceError> {
        let invalid =
            |field, value, rule| PlatformDeviceError::InvalidConfig { field, value, rule };
        let positive = [
            ("travel.in_out_max_m", self.travel.in_out_max_m),
            ("travel.up_down_max_m", self.travel.up_down_max_m),
            ("max_speed_m_per_s[0]", self.max_speed_m_per_s[0]),
            ("max_speed_m_per_s[1]", self.max_speed_m_per_s[1]),
            ("time_constant_s", self.time_constant_s),
            ("encoder_resolution_m", self.encoder_resolution_m),
            ("feedback_period_s", self.feedback_period_s),
        ];
        for (field, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(field, value, "must be finite and positive"));
            }
        }
        if let Some((axis, value)) = self.travel.first_violation(self.start_m) {
            let field = match axis {
                PlatformAxis::InOut => "start_m[0]",
                PlatformAxis::UpDown => "start_m[1]",
            };
            return Err(invalid(field, value, "must lie within the travel"));
        }
        Ok(())
    }
}

/// The two stages: positions, velocities, targets and the last command's outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct PlatformStages {
    config: PlatformDeviceConfig,
    position_m: [f64; 2],
    velocity_m_per_s: [f64; 2],
    target_m: [f64; 2],
    last_command_ns: u64,
    status: PlatformStatus,
}

impl PlatformStages {
    /// Stages at `config.start_m`, standing still.
    pub fn new(config: PlatformDeviceConfig) -> Result<Self, PlatformDeviceError> {
        config.validate()?;
        Ok(Self {
            config,
            position_m: config.start_m,
            velocity_m_per_s: [0.0; 2],
            target_m: config.start_m,
            last_command_ns: 0,
            status: PlatformStatus::Ok,
        })
    }

    pub fn config(&self) -> &PlatformDeviceConfig {
        &self.config
    }

    /// Positions `[in_out, up_down]`, m.
    pub fn position_m(&self) -> [f64; 2] {
        self.position_m
    }

    /// True while either stage has not reached its target.
    pub fn in_motion(&self) -> bool {
        self.position_m != self.target_m
    }

    /// Acts on one command: a stop makes the current position the target; a target inside the
    /// travel becomes the new target; anything else is refused (targets unchanged). Returns
    /// whether the command was accepted.
    pub fn apply(&mut self, stop: bool, target_m: [f64; 2], command_ns: u64) -> bool {
        self.last_command_ns = command_ns;
        if stop {
            self.target_m = self.position_m;
            self.velocity_m_per_s = [0.0; 2];
            self.status = PlatformStatus::Ok;
            return true;
        }
        if let Some((axis, value_m)) = self.config.travel.first_violation(target_m) {
            tracing::warn!(%axis, value_m, "platform target outside the travel refused");
            self.status = PlatformStatus::Refused;
            return false;
        }
        self.target_m = target_m;
        self.status = PlatformStatus::Ok;
        true
    }

    /// Advances both stages by `dt_s` (sub-stepped; see the module docs for the dynamics).
    pub fn step(&mut self, dt_s: f64) {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return;
        }
        let substeps = (dt_s / MAX_SUBSTEP_S).ceil().max(1.0);
        let h = dt_s / substeps;
        for _ in 0..substeps as usize {
            for axis in 0..2 {
                let error_m = self.target_m[axis] - self.position_m[axis];
                if error_m.abs() <= self.config.encoder_resolution_m {
                    self.position_m[axis] = self.target_m[axis];
                    self.velocity_m_per_s[axis] = 0.0;
                    continue;
                }
                let v_max = self.config.max_speed_m_per_s[axis];
                let velocity = (error_m / self.config.time_constant_s).clamp(-v_max, v_max);
                self.velocity_m_per_s[axis] = velocity;
                self.position_m[axis] += velocity * h;
            }
        }
    }

    /// Writes the device's report (stamp left to the caller).
    pub fn write_feedback(&self, feedback: &mut PlatformFeedback) {
        feedback.in_out_m = self.position_m[0];
        feedback.up_down_m = self.position_m[1];
        feedback.in_out_velocity_m_per_s = self.velocity_m_per_s[0];
        feedback.up_down_velocity_m_per_s = self.velocity_m_per_s[1];
        feedback.target_in_out_m = self.target_m[0];
        feedback.target_up_down_m = self.target_m[1];
        feedback.last_command_ns = self.last_command_ns;
        feedback.in_motion = u8::from(self.in_motion());
        feedback.status.set(self.status);
        feedback._reserved = [0; 6];
    }
}

/// The stages served on `hw/platform/command` (in) and `hw/platform/feedback` (out).
pub struct PlatformDeviceServer {
    stages: PlatformStages,
    commands: Subscriber<PlatformCommand>,
    feedback: Publisher<PlatformFeedback>,
    last_tick: Instant,
}

impl PlatformDeviceServer {
    pub fn open(
        context: &Context,
        config: PlatformDeviceConfig,
    ) -> Result<Self, PlatformDeviceError> {
        Ok(Self {
            stages: PlatformStages::new(config)?,
            commands: context.subscriber(HW_PLATFORM_COMMAND)?,
            feedback: context.publisher(HW_PLATFORM_FEEDBACK)?,
            last_tick: Instant::now(),
        })
    }

    /// The stages' positions `[in_out, up_down]`, m from their stops.
    pub fn position_m(&self) -> [f64; 2] {
        self.stages.position_m()
    }

    /// How often [`Self::tick`] should run (the feedback period).
    pub fn period(&self) -> Duration {
        Duration::from_secs_f64(self.stages.config.feedback_period_s)
    }

    /// One controller cycle: act on the commands received since the last cycle (in order),
    /// advance the stages by the elapsed host time, publish the feedback.
    pub fn tick(&mut self) -> Result<(), PlatformDeviceError> {
        while let Some(command) = self.commands.receive()? {
            self.stages.apply(
                command.stop != 0,
                [command.target_in_out_m, command.target_up_down_m],
                command.header.capture_ns,
            );
        }
        let now = Instant::now();
        let dt_s = now.duration_since(self.last_tick).as_secs_f64().min(1.0);
        self.last_tick = now;
        self.stages.step(dt_s);
        let stages = &self.stages;
        self.feedback
            .publish_with(MonotonicClock::read_ns(), |feedback| {
                stages.write_feedback(feedback);
            })?;
        tracing::trace!(position_m = ?stages.position_m, "platform feedback");
        Ok(())
    }
}

/// Errors of [`LocalPlatform`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LocalPlatformError {
    /// A target outside the travel or not finite; nothing changed.
    #[error("{axis} target {value_m} m outside the travel [0, {max_m}] m or not finite")]
    OutOfTravel {
        axis: PlatformAxis,
        value_m: f64,
        max_m: f64,
    },
}

impl DeviceError for LocalPlatformError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::OutOfTravel { .. } => ErrorKind::InvalidRequest,
        }
    }
}

/// The simulated stages as an in-process [`Platform`]: each call first advances them by the
/// host time elapsed since the previous call.
#[derive(Debug, Clone)]
pub struct LocalPlatform {
    stages: PlatformStages,
    last_step: Instant,
    stamp_ns: u64,
}

impl LocalPlatform {
    pub fn new(config: PlatformDeviceConfig) -> Result<Self, PlatformDeviceError> {
        Ok(Self {
            stages: PlatformStages::new(config)?,
            last_step: Instant::now(),
            stamp_ns: 0,
        })
    }

    fn advance(&mut self) -> u64 {
        let now = Instant::now();
        self.stages
            .step(now.duration_since(self.last_step).as_secs_f64());
        self.last_step = now;
        self.stamp_ns = MonotonicClock::read_ns().max(self.stamp_ns);
        self.stamp_ns
    }
}

impl Platform for LocalPlatform {
    type Error = LocalPlatformError;

    fn travel(&self) -> PlatformTravel {
        self.stages.config.travel
    }

    fn move_to(&mut self, in_out_m: f64, up_down_m: f64) -> Result<(), Self::Error> {
        let travel = self.stages.config.travel;
        if let Some((axis, value_m)) = travel.first_violation([in_out_m, up_down_m]) {
            return Err(LocalPlatformError::OutOfTravel {
                axis,
                value_m,
                max_m: travel.max_m(axis),
            });
        }
        let stamp_ns = self.advance();
        self.stages.apply(false, [in_out_m, up_down_m], stamp_ns);
        Ok(())
    }

    fn stop(&mut self) -> Result<(), Self::Error> {
        let stamp_ns = self.advance();
        let here_m = self.stages.position_m();
        self.stages.apply(true, here_m, stamp_ns);
        Ok(())
    }

    fn position(&mut self) -> Result<PlatformPosition, Self::Error> {
        let capture_ns = self.advance();
        let [in_out_m, up_down_m] = self.stages.position_m();
        Ok(PlatformPosition {
            capture_ns,
            in_out_m,
            up_down_m,
            in_motion: self.stages.in_motion(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_hw::platform::conformance::{PlatformConformanceConfig, conformance_suite};

    fn stages() -> PlatformStages {
        PlatformStages::new(PlatformDeviceConfig::default()).expect("default config")
    }

    #[test]
    fn a_long_move_cruises_at_top_speed_then_settles_exactly() {
        let mut stages = stages();
        assert!(stages.apply(false, [0.4, 0.1], 1));
        let dt_s = 0.02;
        // After 1 s the in-out stage (0.4 m away, far beyond v_max * tau = 1 cm) covered
        // exactly v_max * 1 s.
        for _ in 0..50 {
            stages.step(dt_s);
        }
        assert!((stages.position_m()[0] - 0.05).abs() < 1e-9, "{stages:?}");
        assert!(stages.in_motion());
        // The whole move: cruise (0.4 - 0.01) / 0.05 = 7.8 s, then ln(0.01 / 1e-4) * 0.2 = 0.92 s.
        let mut elapsed_s = 1.0;
        while stages.in_motion() {
            stages.step(dt_s);
            elapsed_s += dt_s;
            assert!(elapsed_s < 20.0, "never settled: {stages:?}");
        }
        assert_eq!(stages.position_m(), [0.4, 0.1]);
        assert!(
            (elapsed_s - 8.72).abs() < 0.1,
            "settled after {elapsed_s} s"
        );
        let mut feedback = PlatformFeedback::default();
        stages.write_feedback(&mut feedback);
        assert_eq!(feedback.in_motion, 0);
        assert_eq!(feedback.last_command_ns, 1);
        assert_eq!(feedback.in_out_velocity_m_per_s, 0.0);
    }

    #[test]
    fn the_approach_never_overshoots() {
        let mut stages = stages();
        stages.apply(false, [0.03, 0.0], 1);
        let mut previous = 0.0;
        for _ in 0..200 {
            stages.step(0.013);
            let x = stages.position_m()[0];
            assert!(x >= previous && x <= 0.03, "{x} after {previous}");
            previous = x;
        }
        assert_eq!(stages.position_m()[0], 0.03);
    }

    #[test]
    fn refused_targets_and_stop_keep_the_stages_in_place() {
        let mut stages = stages();
        stages.apply(false, [0.2, 0.2], 1);
        stages.step(0.5);
        let here = stages.position_m();
        assert!(!stages.apply(false, [0.6, 0.1], 2));
        let mut feedback = PlatformFeedback::default();
        stages.write_feedback(&mut feedback);
        assert_eq!(feedback.status, PlatformStatus::Refused);
        assert_eq!(feedback.target_in_out_m, 0.2, "previous target kept");
        assert!(stages.apply(true, [0.0; 2], 3));
        stages.step(1.0);
        assert_eq!(stages.position_m(), here);
        assert!(!stages.in_motion());
    }

    #[test]
    fn invalid_configs_are_refused_naming_the_field() {
        let mut config = PlatformDeviceConfig {
            time_constant_s: 0.0,
            ..PlatformDeviceConfig::default()
        };
        let error = PlatformStages::new(config).expect_err("tau 0");
        assert!(error.to_string().contains("time_constant_s"), "{error}");
        config = PlatformDeviceConfig {
            start_m: [0.0, 2.0],
            ..PlatformDeviceConfig::default()
        };
        let error = PlatformStages::new(config).expect_err("start outside");
        assert!(error.to_string().contains("start_m[1]"), "{error}");
    }

    /// What a deliberately broken platform gets wrong.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Flaw {
        /// `stop` does nothing.
        IgnoresStop,
        /// Targets beyond the travel are clamped and accepted.
        ClampsTargets,
        /// Reports `in_motion = false` while moving.
        NeverInMotion,
    }

    struct Flawed(LocalPlatform, Flaw);

    impl Platform for Flawed {
        type Error = LocalPlatformError;

        fn travel(&self) -> PlatformTravel {
            self.0.travel()
        }

        fn move_to(&mut self, in_out_m: f64, up_down_m: f64) -> Result<(), Self::Error> {
            if self.1 == Flaw::ClampsTargets {
                let travel = self.0.travel();
                let clamp = |v: f64, max: f64| if v.is_nan() { 0.0 } else { v.clamp(0.0, max) };
                return self.0.move_to(
                    clamp(in_out_m, travel.in_out_max_m),
                    clamp(up_down_m, travel.up_down_max_m),
                );
            }
            self.0.move_to(in_out_m, up_down_m)
        }

        fn stop(&mut self) -> Result<(), Self::Error> {
            match self.1 {
                Flaw::IgnoresStop => Ok(()),
                _ => self.0.stop(),
            }
        }

        fn position(&mut self) -> Result<PlatformPosition, Self::Error> {
            let mut position = self.0.position()?;
            if self.1 == Flaw::NeverInMotion {
                position.in_motion = false;
            }
            Ok(position)
        }
    }

    #[test]
    fn broken_platforms_fail_the_right_check() {
        for (flaw, expected) in [
            (Flaw::IgnoresStop, "stop_halts_motion"),
            (Flaw::ClampsTargets, "refuses_targets_outside_travel"),
            (Flaw::NeverInMotion, "move_reaches_target_without_overshoot"),
        ] {
            let result = conformance_suite(&PlatformConformanceConfig::default(), || {
                // Fast stages, so the flaw that lets a move run to the end of the travel
                // does not take 16 s.
                let fast = PlatformDeviceConfig {
                    max_speed_m_per_s: [0.5, 0.5],
                    time_constant_s: 0.05,
                    ..PlatformDeviceConfig::default()
                };
                Flawed(LocalPlatform::new(fast).expect("local platform"), flaw)
            });
            match result {
                Err(
                    harvest_hw::conformance::ConformanceError::Violated { check, .. }
                    | harvest_hw::conformance::ConformanceError::WrongOutcome { check, .. },
                ) => assert_eq!(check, expected, "{flaw:?}"),
                other => panic!("{flaw:?}: expected {expected} to fail, got {other:?}"),
            }
        }
    }

    #[test]
    fn the_local_platform_passes_the_conformance_suite() {
        let report = conformance_suite(&PlatformConformanceConfig::default(), || {
            LocalPlatform::new(PlatformDeviceConfig::default()).expect("local platform")
        })
        .expect("conformance");
        assert_eq!(report.checks_passed.len(), 5, "{report:?}");
    }
}
