//! The picking cycle of one arm as a plain state machine (paper 003, section 3.3 and Fig. 9a):
//! Approach -> Attach (valve open, wait for the pressure-confirmed attachment, twist the
//! end-effector) -> Retract to the drop-off pose with suction held -> Release (valve closed,
//! apple drops) -> Idle. A failed attachment, or an apple lost on the way back, closes the valve
//! at once and skips Release (eq. 11, first two lines). Which arm may open its valve is decided
//! outside (the vacuum/coordination process, eq. 11): the arm requests, then waits for the
//! valve status.
//!
//! The machine is driven by [`PickingCycle::step`] once per control period with the time, the
//! joint feedback, the valve and attachment status, an optional new target and the other arm's
//! state; it returns rate commands from the tracking controller, the valve request, the phase
//! and at most one event. It reads no clock and does no I/O.
//!
//! Timing. With the simulated servos following the trajectories, a target 0.52 m from the home
//! end-effector position takes about 1.9 s to approach and 1.9 s to retract at the default 0.6
//! speed fraction (the field setting of section 4.2), and Attach + Release take about 0.55 s,
//! so one cycle lasts about 4.3 s: the single-arm interval of Fig. 12 (4.5 s baseline, 2.25 s
//! per apple with both arms interleaved; derivation in `CONTROLLER.md`). The tests
//! `cycle_timing_matches_the_fig_12_analysis` and `two_arms_interleave_as_in_the_2024_timeline`
//! check this.

use serde::{Deserialize, Serialize};
use thiserror::Error;
use tracing::{debug, trace, warn};

use crate::controller::{
    GainsError, JointCommand, TrackingController, TrackingGains, TrackingReference,
};
use crate::trajectory::{JointTrajectory, TrajectoryError};
use harvest_robot_model::clearance::{DEFAULT_CLEARANCE_M, SweptPath};
use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::kinematics::{IkError, forward, inverse, inverse_unchecked};
use harvest_robot_model::params::{ArmParams, ParamsError};

/// Samples of our own planned approach used for the clearance check.
const OWN_SWEEP_SAMPLES: usize = 16;
/// Samples of each straight joint-space leg used for the clearance check.
const LEG_SWEEP_SAMPLES: usize = 8;

/// Phase of the picking cycle (section 3.3: Approach, Detach, Retract, Release; the paper's
/// Detach is our Attach, which includes the end-effector twist).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CyclePhase {
    /// At rest (normally at the home/drop-off pose), ready for a target.
    Idle,
    /// Moving to the apple.
    Approach,
    /// At the apple: valve requested open, waiting for attachment, then twisting.
    Attach,
    /// Moving back to the drop-off pose (suction kept while an apple is held).
    Retract,
    /// At the drop-off pose with the valve closed, letting the apple fall.
    Release,
}

/// What this arm asks of its valves (Fig. 3): open to the vacuum source (attach and hold) or
/// closed to the source and open to the atmosphere (release, and the resting state).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ValveRequest {
    /// Closed to the vacuum source, vented (paper: `not Open_Valve`).
    Closed,
    /// Open to the vacuum source (paper: `Open_Valve`).
    Open,
}

/// A target assigned to this arm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetRequest {
    /// Identifier chosen by the assigner; repeats of the current target are ignored.
    pub id: u64,
    /// Picking point in the robot frame, m.
    pub position_m: [f64; 3],
    /// Capture time of the image the target was detected in, ns (same clock as `now_ns`).
    pub detected_at_ns: u64,
}

/// What this arm needs to know about the other arm for the clearance check.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OtherArmState {
    /// Its phase.
    pub phase: CyclePhase,
    /// Its end-effector position, robot frame, m.
    pub end_effector_m: [f64; 3],
    /// Where it is moving to, robot frame, m (required while it approaches).
    pub goal_m: Option<[f64; 3]>,
}

impl OtherArmState {
    /// The state another [`PickingCycle`] reported in its last output.
    pub fn from_output(output: &CycleOutput) -> Self {
        Self {
            phase: output.phase,
            end_effector_m: output.end_effector_m,
            goal_m: output.goal_m,
        }
    }
}

/// Inputs of one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleInput {
    /// Current time, ns (monotonic).
    pub now_ns: u64,
    /// Measured joint positions.
    pub joints: JointPosition,
    /// Time the joint positions were measured, ns.
    pub joints_stamp_ns: u64,
    /// True when this arm's valve is open to the vacuum source (the grant of our request).
    pub valve_open: bool,
    /// True when the pressure sensor of this arm says an apple seals the end-effector.
    pub apple_attached: bool,
    /// A target offered to this arm this step, if any.
    pub target: Option<TargetRequest>,
    /// The other arm's state; `None` when there is no other arm (single-arm operation).
    pub other_arm: Option<OtherArmState>,
}

/// Why a target was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TargetRejection {
    /// The position has a NaN or infinite coordinate.
    #[error("target {id} position {position_m:?} is not finite")]
    NonFinite {
        /// Target id.
        id: u64,
        /// The position.
        position_m: [f64; 3],
    },
    /// The detection is older than the configured maximum.
    #[error("target {id} is stale: detected {age_s:.3} s ago, maximum {max_age_s:.3} s")]
    Stale {
        /// Target id.
        id: u64,
        /// Age of the detection, s.
        age_s: f64,
        /// Configured maximum, s.
        max_age_s: f64,
    },
    /// The detection time is after `now_ns`.
    #[error("target {id} is stamped {ahead_s:.6} s in the future")]
    FromFuture {
        /// Target id.
        id: u64,
        /// How far ahead, s.
        ahead_s: f64,
    },
    /// The target is outside this arm's workspace.
    #[error("target {id} is unreachable: {reason}")]
    Unreachable {
        /// Target id.
        id: u64,
        /// Why (inverse kinematics).
        reason: IkError,
    },
    /// This arm is in a cycle already (retry when Idle).
    #[error("target {id} refused: arm busy in phase {phase:?}")]
    Busy {
        /// Target id.
        id: u64,
        /// Current phase.
        phase: CyclePhase,
    },
    /// The motion would pass closer to the other arm than the clearance (retry later).
    #[error(
        "target {id} refused: swept paths come within {min_distance_m:.3} m of the other arm (clearance {clearance_m:.3} m)"
    )]
    ClearanceConflict {
        /// Target id.
        id: u64,
        /// Smallest tube-to-tube distance found, m.
        min_distance_m: f64,
        /// Configured clearance, m.
        clearance_m: f64,
    },
    /// The other arm is approaching but did not report its goal (retry later).
    #[error("target {id} refused: the other arm is approaching an unknown goal")]
    OtherArmGoalUnknown {
        /// Target id.
        id: u64,
    },
    /// The other arm's reported position has no kinematic solution.
    #[error("target {id} refused: other arm pose unknown ({reason})")]
    OtherArmPoseUnknown {
        /// Target id.
        id: u64,
        /// Why its position could not be inverted.
        reason: IkError,
    },
    /// Joint feedback is invalid or stale, so no motion can start (retry when it recovers).
    #[error("target {id} refused: joint feedback invalid or stale")]
    NoFeedback {
        /// Target id.
        id: u64,
    },
    /// No trajectory could be planned.
    #[error("target {id} refused: planning failed: {reason}")]
    Planning {
        /// Target id.
        id: u64,
        /// Planner error.
        reason: TrajectoryError,
    },
}

impl TargetRejection {
    /// True when the same target may be offered again later (the refusal depends on this or
    /// the other arm's current activity, not on the target itself).
    pub fn is_retryable(&self) -> bool {
        matches!(
            self,
            TargetRejection::Busy { .. }
                | TargetRejection::NoFeedback { .. }
                | TargetRejection::ClearanceConflict { .. }
                | TargetRejection::OtherArmGoalUnknown { .. }
        )
    }
}

/// The answer to an offered target.
#[derive(Debug, Clone, PartialEq)]
pub enum TargetDecision {
    /// The cycle started; the arm is approaching.
    Accepted {
        /// Target id.
        id: u64,
    },
    /// The target was refused.
    Rejected(TargetRejection),
}

/// Something that happened during a step (at most one per step).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum CycleEvent {
    /// Reached the apple; valve requested open.
    ApproachComplete,
    /// Did not settle at the apple in time; retracting without attaching.
    ApproachTimeout,
    /// The valve was not granted in time; retracting.
    ValveGrantTimeout,
    /// Pressure feedback confirmed the attachment; twisting.
    Attached,
    /// No attachment within the timeout; valve closed, retracting (Fig. 9, failure branch).
    AttachFailed,
    /// The apple came off after attaching; valve closed immediately (eq. 11).
    AppleLost,
    /// The twist finished; retracting with the apple.
    DetachComplete,
    /// Back at the drop-off with an apple; valve requested closed.
    RetractComplete,
    /// The valve did not report closed in time at the drop-off.
    ValveCloseTimeout,
    /// The cycle ended; `harvested` tells whether an apple was released.
    CycleComplete {
        /// True when an apple reached the drop-off and was released.
        harvested: bool,
    },
    /// Joint feedback was non-finite or older than allowed; the arm was stopped.
    FeedbackInvalid {
        /// Feedback age, s.
        age_s: f64,
    },
}

/// Outputs of one step.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleOutput {
    /// Phase after this step.
    pub phase: CyclePhase,
    /// Joint rate command for the servos.
    pub command: JointCommand,
    /// Requested valve state.
    pub valve_request: ValveRequest,
    /// Answer to the target offered this step, if any and not a repeat.
    pub target_decision: Option<TargetDecision>,
    /// Event of this step, if any.
    pub event: Option<CycleEvent>,
    /// Measured end-effector position, robot frame, m.
    pub end_effector_m: [f64; 3],
    /// End-effector goal of the current or next motion, robot frame, m.
    pub goal_m: Option<[f64; 3]>,
    /// Tracking reference used this step (for logging).
    pub reference: Option<TrackingReference>,
    /// Id of the target of the running cycle.
    pub target_id: Option<u64>,
}

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
    /// End-effector twist applied to detach the apple, rad.
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
    /// Tracking controller gains.
    pub gains: TrackingGains,
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
            detach_twist_rad: std::f64::consts::FRAC_PI_4,
            release_dwell_s: 0.15,
            max_target_age_s: 2.0,
            max_feedback_age_s: 0.05,
            clearance_m: DEFAULT_CLEARANCE_M,
            nominal_period_s: 0.005,
            gains: TrackingGains::default(),
        }
    }
}

/// Why a [`PickingCycle`] could not be built.
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

/// A trajectory being followed. Without a trajectory (planning failed, which valid goals
/// never cause) the reference is the goal itself and the rate clamps pace the motion.
#[derive(Debug, Clone, PartialEq)]
struct Motion {
    trajectory: Option<JointTrajectory>,
    start_ns: u64,
    goal: JointPosition,
}

impl Motion {
    fn duration_s(&self) -> f64 {
        self.trajectory
            .as_ref()
            .map_or(0.0, JointTrajectory::duration_s)
    }

    fn reference(
        &self,
        links: &harvest_robot_model::params::LinkParams,
        t_s: f64,
    ) -> TrackingReference {
        match &self.trajectory {
            Some(trajectory) => {
                TrackingReference::from_joint_sample(links, &trajectory.sample(t_s))
            }
            None => TrackingReference::hold(links, &self.goal),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
enum AttachStage {
    WaitingValve { since_ns: u64 },
    WaitingAttachment { since_ns: u64 },
    Twisting { motion: Motion },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum ReleaseStage {
    WaitingValveClosed { since_ns: u64 },
    Dropping { since_ns: u64 },
}

#[derive(Debug, Clone, PartialEq)]
enum State {
    Idle,
    Approach {
        motion: Motion,
        target: TargetRequest,
    },
    Attach {
        target: TargetRequest,
        hold: JointPosition,
        stage: AttachStage,
    },
    Retract {
        motion: Motion,
        target_id: u64,
        apple: bool,
    },
    Release {
        target_id: u64,
        stage: ReleaseStage,
    },
}

impl State {
    fn phase(&self) -> CyclePhase {
        match self {
            State::Idle => CyclePhase::Idle,
            State::Approach { .. } => CyclePhase::Approach,
            State::Attach { .. } => CyclePhase::Attach,
            State::Retract { .. } => CyclePhase::Retract,
            State::Release { .. } => CyclePhase::Release,
        }
    }

    fn target_id(&self) -> Option<u64> {
        match self {
            State::Idle => None,
            State::Approach { target, .. } | State::Attach { target, .. } => Some(target.id),
            State::Retract { target_id, .. } | State::Release { target_id, .. } => Some(*target_id),
        }
    }
}

fn elapsed_s(now_ns: u64, since_ns: u64) -> f64 {
    now_ns.saturating_sub(since_ns) as f64 * 1e-9
}

fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Progress of a motion at one step.
enum MotionProgress {
    Running,
    Arrived,
    TimedOut,
}

/// The picking cycle of one arm.
#[derive(Debug, Clone, PartialEq)]
pub struct PickingCycle {
    params: ArmParams,
    other_params: ArmParams,
    config: CycleConfig,
    controller: TrackingController,
    state: State,
    valve_request: ValveRequest,
    last_now_ns: Option<u64>,
    needs_replan: bool,
}

impl PickingCycle {
    /// A cycle for the arm `params`, checking clearance against the arm `other_params`.
    pub fn new(
        params: ArmParams,
        other_params: ArmParams,
        config: CycleConfig,
    ) -> Result<Self, CycleConfigError> {
        params.validate()?;
        other_params.validate()?;
        config.validate()?;
        Ok(Self {
            params,
            other_params,
            config,
            controller: TrackingController::new(params, config.gains)?,
            state: State::Idle,
            valve_request: ValveRequest::Closed,
            last_now_ns: None,
            needs_replan: false,
        })
    }

    /// Current phase.
    pub fn phase(&self) -> CyclePhase {
        self.state.phase()
    }

    /// The arm parameters.
    pub fn params(&self) -> &ArmParams {
        &self.params
    }

    /// The configuration.
    pub fn config(&self) -> &CycleConfig {
        &self.config
    }

    /// One control period. See the module documentation.
    pub fn step(&mut self, input: &CycleInput) -> CycleOutput {
        let dt_s = match self.last_now_ns {
            None => self.config.nominal_period_s,
            Some(last) if input.now_ns > last => elapsed_s(input.now_ns, last),
            Some(_) => 0.0,
        };
        self.last_now_ns = Some(input.now_ns);
        let end_effector_m = forward(&self.params.links, &input.joints);

        let feedback_age_s = if input.joints_stamp_ns > input.now_ns {
            0.0
        } else {
            elapsed_s(input.now_ns, input.joints_stamp_ns)
        };
        if !input.joints.is_finite() || feedback_age_s > self.config.max_feedback_age_s {
            warn!(
                arm = %self.params.arm,
                feedback_age_s,
                "joint feedback invalid or stale: stopping the arm"
            );
            self.needs_replan = !matches!(self.state, State::Idle);
            let decision = match input.target {
                Some(t) if matches!(self.state, State::Idle) => {
                    Some(TargetDecision::Rejected(TargetRejection::NoFeedback {
                        id: t.id,
                    }))
                }
                Some(t) => self.busy_or_repeat(&t),
                None => None,
            };
            return self.output(
                JointCommand::STOP,
                decision,
                Some(CycleEvent::FeedbackInvalid {
                    age_s: feedback_age_s,
                }),
                end_effector_m,
                None,
            );
        }
        if self.needs_replan {
            self.replan(input);
        }

        let decision = match input.target {
            Some(target) if matches!(self.state, State::Idle) => Some(self.offer(&target, input)),
            Some(target) => self.busy_or_repeat(&target),
            None => None,
        };
        let event = self.advance(input);
        if let Some(event) = event {
            debug!(arm = %self.params.arm, ?event, phase = ?self.state.phase(), "picking cycle");
        }
        let (command, reference) = self.command(input, dt_s);
        trace!(
            arm = %self.params.arm,
            phase = ?self.state.phase(),
            ?command,
            "picking cycle step"
        );
        self.output(command, decision, event, end_effector_m, reference)
    }

    fn output(
        &self,
        command: JointCommand,
        target_decision: Option<TargetDecision>,
        event: Option<CycleEvent>,
        end_effector_m: [f64; 3],
        reference: Option<TrackingReference>,
    ) -> CycleOutput {
        let goal_m = match &self.state {
            State::Idle => None,
            State::Approach { target, .. } | State::Attach { target, .. } => {
                Some(target.position_m)
            }
            State::Retract { motion, .. } => Some(forward(&self.params.links, &motion.goal)),
            State::Release { .. } => Some(forward(&self.params.links, &self.params.home)),
        };
        CycleOutput {
            phase: self.state.phase(),
            command,
            valve_request: self.valve_request,
            target_decision,
            event,
            end_effector_m,
            goal_m,
            reference,
            target_id: self.state.target_id(),
        }
    }

    /// Decision for a target offered while busy: none for a repeat of the current target.
    fn busy_or_repeat(&self, target: &TargetRequest) -> Option<TargetDecision> {
        if self.state.target_id() == Some(target.id) {
            return None;
        }
        Some(TargetDecision::Rejected(TargetRejection::Busy {
            id: target.id,
            phase: self.state.phase(),
        }))
    }

    /// Validates a target offered while idle and starts the approach if it passes.
    fn offer(&mut self, target: &TargetRequest, input: &CycleInput) -> TargetDecision {
        match self.plan_approach(target, input) {
            Ok(motion) => {
                debug!(arm = %self.params.arm, id = target.id, position_m = ?target.position_m,
                    duration_s = motion.duration_s(), "target accepted");
                self.controller.reset();
                self.state = State::Approach {
                    motion,
                    target: *target,
                };
                TargetDecision::Accepted { id: target.id }
            }
            Err(reason) => {
                warn!(arm = %self.params.arm, %reason, "target rejected");
                TargetDecision::Rejected(reason)
            }
        }
    }

    fn plan_approach(
        &self,
        target: &TargetRequest,
        input: &CycleInput,
    ) -> Result<Motion, TargetRejection> {
        let id = target.id;
        if target.position_m.iter().any(|v| !v.is_finite()) {
            return Err(TargetRejection::NonFinite {
                id,
                position_m: target.position_m,
            });
        }
        if target.detected_at_ns > input.now_ns {
            return Err(TargetRejection::FromFuture {
                id,
                ahead_s: elapsed_s(target.detected_at_ns, input.now_ns),
            });
        }
        let age_s = elapsed_s(input.now_ns, target.detected_at_ns);
        if age_s > self.config.max_target_age_s {
            return Err(TargetRejection::Stale {
                id,
                age_s,
                max_age_s: self.config.max_target_age_s,
            });
        }
        let goal = inverse(&self.params, target.position_m)
            .map_err(|reason| TargetRejection::Unreachable { id, reason })?;
        let here_m = forward(&self.params.links, &input.joints);
        let all = match self.standoff(target.position_m, here_m) {
            Some(via) => [input.joints, via, goal],
            None => [input.joints, goal, goal],
        };
        let count = if all[1] == all[2] { 2 } else { 3 };
        let trajectory = JointTrajectory::plan(
            &self.params,
            all.get(..count).unwrap_or(&all),
            &JointVelocity::ZERO,
            self.config.speed_fraction,
        )
        .map_err(|reason| TargetRejection::Planning { id, reason })?;
        if let Some(other) = &input.other_arm {
            self.check_clearance(id, &trajectory, &goal, other)?;
        }
        Ok(Motion {
            trajectory: Some(trajectory),
            start_ns: input.now_ns,
            goal,
        })
    }

    /// Refuses the motion when our sweep (approach, then straight back home) comes closer to
    /// the other arm's remaining sweep than the clearance.
    fn check_clearance(
        &self,
        id: u64,
        approach: &JointTrajectory,
        goal: &JointPosition,
        other: &OtherArmState,
    ) -> Result<(), TargetRejection> {
        let links = &self.params.links;
        let mut ours = SweptPath::new();
        for k in 0..=OWN_SWEEP_SAMPLES {
            let t = approach.duration_s() * k as f64 / OWN_SWEEP_SAMPLES as f64;
            ours.push(links, &approach.sample(t).position);
        }
        ours.push_joint_line(links, goal, &self.params.home, LEG_SWEEP_SAMPLES);

        let other_links = &self.other_params.links;
        let other_home = self.other_params.home;
        let now = inverse_unchecked(other_links, other.end_effector_m)
            .map_err(|reason| TargetRejection::OtherArmPoseUnknown { id, reason })?;
        let mut theirs = SweptPath::new();
        match other.phase {
            CyclePhase::Idle | CyclePhase::Release => {
                theirs.push(other_links, &now);
            }
            CyclePhase::Attach => {
                theirs.push_joint_line(other_links, &now, &other_home, LEG_SWEEP_SAMPLES);
            }
            CyclePhase::Retract => {
                let goal = match other.goal_m {
                    Some(g) => inverse_unchecked(other_links, g)
                        .map_err(|reason| TargetRejection::OtherArmPoseUnknown { id, reason })?,
                    None => other_home,
                };
                theirs.push_joint_line(other_links, &now, &goal, LEG_SWEEP_SAMPLES);
            }
            CyclePhase::Approach => {
                let goal_m = other
                    .goal_m
                    .ok_or(TargetRejection::OtherArmGoalUnknown { id })?;
                let goal = inverse_unchecked(other_links, goal_m)
                    .map_err(|reason| TargetRejection::OtherArmPoseUnknown { id, reason })?;
                theirs.push_joint_line(other_links, &now, &goal, LEG_SWEEP_SAMPLES);
                theirs.push_joint_line(other_links, &goal, &other_home, LEG_SWEEP_SAMPLES);
            }
        }
        let min_distance_m = ours.min_distance_m(&theirs);
        if min_distance_m < self.config.clearance_m {
            return Err(TargetRejection::ClearanceConflict {
                id,
                min_distance_m,
                clearance_m: self.config.clearance_m,
            });
        }
        Ok(())
    }

    /// Plans a motion from the measured joints to `goal`, starting now at rest.
    fn motion_to(&self, input: &CycleInput, goal: JointPosition) -> Motion {
        self.motion_via(input, None, goal)
    }

    /// Plans a motion from the measured joints through `via` (if any) to `goal`, starting now
    /// at rest.
    fn motion_via(
        &self,
        input: &CycleInput,
        via: Option<JointPosition>,
        goal: JointPosition,
    ) -> Motion {
        let all = [input.joints, via.unwrap_or(goal), goal];
        let waypoints = if via.is_some() { &all[..] } else { &all[..2] };
        let trajectory = JointTrajectory::plan(
            &self.params,
            waypoints,
            &JointVelocity::ZERO,
            self.config.speed_fraction,
        )
        .inspect_err(|error| {
            warn!(arm = %self.params.arm, %error, "motion planning failed: direct regulation");
        })
        .ok();
        Motion {
            trajectory,
            start_ns: input.now_ns,
            goal,
        }
    }

    /// After a feedback outage the arm was stopped: restart the running motion from where the
    /// arm is, at rest.
    fn replan(&mut self, input: &CycleInput) {
        self.needs_replan = false;
        let goal = match &self.state {
            State::Approach { motion, .. } | State::Retract { motion, .. } => motion.goal,
            State::Attach {
                stage: AttachStage::Twisting { motion },
                ..
            } => motion.goal,
            _ => return,
        };
        let fresh = self.motion_to(input, goal);
        match &mut self.state {
            State::Approach { motion, .. }
            | State::Retract { motion, .. }
            | State::Attach {
                stage: AttachStage::Twisting { motion },
                ..
            } => *motion = fresh,
            _ => {}
        }
    }

    fn progress(&self, motion: &Motion, input: &CycleInput) -> MotionProgress {
        let t = elapsed_s(input.now_ns, motion.start_ns);
        let duration = motion.duration_s();
        if t < duration {
            return MotionProgress::Running;
        }
        let links = &self.params.links;
        let position_error =
            distance_m(forward(links, &input.joints), forward(links, &motion.goal));
        let twist_error = (input.joints.twist_rad - motion.goal.twist_rad).abs();
        if position_error <= self.config.arrival_tolerance_m
            && twist_error <= self.config.twist_tolerance_rad
        {
            MotionProgress::Arrived
        } else if t >= duration + self.config.settle_timeout_s {
            MotionProgress::TimedOut
        } else {
            MotionProgress::Running
        }
    }

    /// The point `approach_standoff_m` short of `position_m` along -x, as joints, when it is
    /// reachable and lies ahead of `from_m` in x (otherwise the detour is skipped).
    fn standoff(&self, position_m: [f64; 3], from_m: [f64; 3]) -> Option<JointPosition> {
        let standoff_m = self.config.approach_standoff_m;
        let [x, y, z] = position_m;
        let point = [x - standoff_m, y, z];
        (standoff_m > 0.0 && from_m[0] < point[0])
            .then(|| inverse(&self.params, point).ok())
            .flatten()
    }

    /// Starts the retract to home, first pulling straight back by the approach standoff so
    /// the path mirrors the approach; `apple` tells whether an apple is held.
    fn retract(&mut self, input: &CycleInput, target_id: u64, apple: bool) {
        if !apple {
            self.valve_request = ValveRequest::Closed;
        }
        let home_m = forward(&self.params.links, &self.params.home);
        let here_m = forward(&self.params.links, &input.joints);
        let pullback = self.standoff(here_m, home_m);
        // Keep the twist during the pull-back; it unwinds on the long leg home.
        let pullback = pullback.map(|q| {
            self.params
                .position_limits
                .clamp(&q.with_twist(input.joints.twist_rad))
        });
        let motion = self.motion_via(input, pullback, self.params.home);
        self.state = State::Retract {
            motion,
            target_id,
            apple,
        };
    }

    /// Runs the transition logic of the current state; at most one event.
    fn advance(&mut self, input: &CycleInput) -> Option<CycleEvent> {
        let now = input.now_ns;
        let cfg = self.config;
        match std::mem::replace(&mut self.state, State::Idle) {
            State::Idle => None,
            State::Approach { motion, target } => match self.progress(&motion, input) {
                MotionProgress::Running => {
                    self.state = State::Approach { motion, target };
                    None
                }
                MotionProgress::Arrived => {
                    self.valve_request = ValveRequest::Open;
                    self.state = State::Attach {
                        target,
                        hold: motion.goal,
                        stage: AttachStage::WaitingValve { since_ns: now },
                    };
                    Some(CycleEvent::ApproachComplete)
                }
                MotionProgress::TimedOut => {
                    warn!(arm = %self.params.arm, id = target.id, "approach did not settle");
                    self.retract(input, target.id, false);
                    Some(CycleEvent::ApproachTimeout)
                }
            },
            State::Attach {
                target,
                hold,
                stage,
            } => match stage {
                AttachStage::WaitingValve { since_ns } => {
                    if input.valve_open {
                        self.state = State::Attach {
                            target,
                            hold,
                            stage: AttachStage::WaitingAttachment { since_ns: now },
                        };
                        None
                    } else if elapsed_s(now, since_ns) > cfg.valve_grant_timeout_s {
                        warn!(arm = %self.params.arm, id = target.id, "valve not granted");
                        self.retract(input, target.id, false);
                        Some(CycleEvent::ValveGrantTimeout)
                    } else {
                        self.state = State::Attach {
                            target,
                            hold,
                            stage,
                        };
                        None
                    }
                }
                AttachStage::WaitingAttachment { since_ns } => {
                    if input.apple_attached {
                        let twist_goal = input.joints.with_twist(cfg.detach_twist_rad);
                        let twist_goal = self.params.position_limits.clamp(&twist_goal);
                        let motion = self.motion_to(input, twist_goal);
                        self.state = State::Attach {
                            target,
                            hold,
                            stage: AttachStage::Twisting { motion },
                        };
                        Some(CycleEvent::Attached)
                    } else if elapsed_s(now, since_ns) > cfg.attach_timeout_s {
                        warn!(arm = %self.params.arm, id = target.id, "attachment failed");
                        self.retract(input, target.id, false);
                        Some(CycleEvent::AttachFailed)
                    } else {
                        self.state = State::Attach {
                            target,
                            hold,
                            stage: AttachStage::WaitingAttachment { since_ns },
                        };
                        None
                    }
                }
                AttachStage::Twisting { motion } => {
                    if !input.apple_attached {
                        warn!(arm = %self.params.arm, id = target.id, "apple lost while twisting");
                        self.retract(input, target.id, false);
                        return Some(CycleEvent::AppleLost);
                    }
                    match self.progress(&motion, input) {
                        MotionProgress::Running => {
                            self.state = State::Attach {
                                target,
                                hold,
                                stage: AttachStage::Twisting { motion },
                            };
                            None
                        }
                        MotionProgress::Arrived | MotionProgress::TimedOut => {
                            self.retract(input, target.id, true);
                            Some(CycleEvent::DetachComplete)
                        }
                    }
                }
            },
            State::Retract {
                motion,
                target_id,
                apple,
            } => {
                if apple && !input.apple_attached {
                    warn!(arm = %self.params.arm, id = target_id, "apple lost during retract");
                    self.valve_request = ValveRequest::Closed;
                    self.state = State::Retract {
                        motion,
                        target_id,
                        apple: false,
                    };
                    return Some(CycleEvent::AppleLost);
                }
                match self.progress(&motion, input) {
                    MotionProgress::Running => {
                        self.state = State::Retract {
                            motion,
                            target_id,
                            apple,
                        };
                        None
                    }
                    MotionProgress::Arrived | MotionProgress::TimedOut if apple => {
                        self.valve_request = ValveRequest::Closed;
                        self.state = State::Release {
                            target_id,
                            stage: ReleaseStage::WaitingValveClosed { since_ns: now },
                        };
                        Some(CycleEvent::RetractComplete)
                    }
                    MotionProgress::Arrived | MotionProgress::TimedOut => {
                        self.valve_request = ValveRequest::Closed;
                        Some(CycleEvent::CycleComplete { harvested: false })
                    }
                }
            }
            State::Release { target_id, stage } => match stage {
                ReleaseStage::WaitingValveClosed { since_ns } => {
                    if !input.valve_open {
                        self.state = State::Release {
                            target_id,
                            stage: ReleaseStage::Dropping { since_ns: now },
                        };
                        None
                    } else if elapsed_s(now, since_ns) > cfg.valve_grant_timeout_s {
                        warn!(arm = %self.params.arm, id = target_id, "valve did not close");
                        Some(CycleEvent::ValveCloseTimeout)
                    } else {
                        self.state = State::Release { target_id, stage };
                        None
                    }
                }
                ReleaseStage::Dropping { since_ns } => {
                    if elapsed_s(now, since_ns) >= cfg.release_dwell_s {
                        Some(CycleEvent::CycleComplete { harvested: true })
                    } else {
                        self.state = State::Release { target_id, stage };
                        None
                    }
                }
            },
        }
    }

    /// Rate command for the current state.
    fn command(
        &mut self,
        input: &CycleInput,
        dt_s: f64,
    ) -> (JointCommand, Option<TrackingReference>) {
        let links = self.params.links;
        let reference = match &self.state {
            State::Idle => return (JointCommand::default(), None),
            State::Approach { motion, .. }
            | State::Retract { motion, .. }
            | State::Attach {
                stage: AttachStage::Twisting { motion },
                ..
            } => motion.reference(&links, elapsed_s(input.now_ns, motion.start_ns)),
            State::Attach { hold, .. } => TrackingReference::hold(&links, hold),
            State::Release { .. } => TrackingReference::hold(&links, &self.params.home),
        };
        let command = self.controller.step(&reference, &input.joints, dt_s);
        (command, Some(reference))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::servo_model::FirstOrderServo;

    const PERIOD_NS: u64 = 5_000_000; // 200 Hz
    const SUBSTEPS: u64 = 5;
    /// Suction cup capture radius used by the simulated world (section 2.2: +-1.5 cm).
    const CAPTURE_RADIUS_M: f64 = 0.015;

    /// One arm with simulated servos, valve and apple.
    struct World {
        cycle: PickingCycle,
        servo: FirstOrderServo,
        now_ns: u64,
        valve_open: bool,
        valve_obeys: bool,
        attached: bool,
        apple_m: [f64; 3],
        sealable: bool,
        drop_apple_in_retract: bool,
        feedback_delay_ns: u64,
        phase_log: Vec<(CyclePhase, f64)>,
        events: Vec<(CycleEvent, f64)>,
        outputs: Vec<CycleOutput>,
        max_tracking_error_m: f64,
    }

    impl World {
        fn new(params: ArmParams, other: ArmParams, apple_m: [f64; 3]) -> Self {
            let cycle = PickingCycle::new(params, other, CycleConfig::default()).unwrap();
            Self {
                cycle,
                servo: FirstOrderServo::new(params.position_limits, 0.02, params.home),
                now_ns: 10_000_000_000,
                valve_open: false,
                valve_obeys: true,
                attached: false,
                apple_m,
                sealable: true,
                drop_apple_in_retract: false,
                feedback_delay_ns: 0,
                phase_log: vec![(CyclePhase::Idle, 0.0)],
                events: Vec::new(),
                outputs: Vec::new(),
                max_tracking_error_m: 0.0,
            }
        }

        fn t_s(&self) -> f64 {
            (self.now_ns - 10_000_000_000) as f64 * 1e-9
        }

        fn input(&self, target: Option<TargetRequest>, other: Option<OtherArmState>) -> CycleInput {
            CycleInput {
                now_ns: self.now_ns,
                joints: self.servo.position,
                joints_stamp_ns: self.now_ns - self.feedback_delay_ns,
                valve_open: self.valve_open,
                apple_attached: self.attached,
                target,
                other_arm: other,
            }
        }

        fn tick(
            &mut self,
            target: Option<TargetRequest>,
            other: Option<OtherArmState>,
        ) -> CycleOutput {
            let out = self.cycle.step(&self.input(target, other));
            let t = self.t_s();
            if let Some(r) = &out.reference
                && matches!(out.phase, CyclePhase::Approach | CyclePhase::Retract)
            {
                let e = distance_m(r.position_m, out.end_effector_m);
                self.max_tracking_error_m = self.max_tracking_error_m.max(e);
            }
            if self.phase_log.last().map(|p| p.0) != Some(out.phase) {
                self.phase_log.push((out.phase, t));
            }
            if let Some(e) = out.event {
                self.events.push((e, t));
            }
            if self.valve_obeys {
                self.valve_open = out.valve_request == ValveRequest::Open;
            }
            let ee = forward(&self.cycle.params.links, &self.servo.position);
            if self.valve_open
                && self.sealable
                && !self.attached
                && distance_m(ee, self.apple_m) <= CAPTURE_RADIUS_M
            {
                self.attached = true;
            }
            if !self.valve_open
                || (self.drop_apple_in_retract && out.phase == CyclePhase::Retract && t > 0.0)
            {
                self.attached = false;
            }
            for _ in 0..SUBSTEPS {
                self.servo
                    .step(&out.command.velocity, &JointVelocity::ZERO, 1e-3);
            }
            self.now_ns += PERIOD_NS;
            self.outputs.push(out.clone());
            out
        }

        fn target(&self, id: u64) -> TargetRequest {
            TargetRequest {
                id,
                position_m: self.apple_m,
                detected_at_ns: self.now_ns - 100_000_000,
            }
        }

        /// Offers the apple once, then runs until Idle again (or `max_s`).
        fn run_cycle(&mut self, max_s: f64) -> TargetDecision {
            let target = self.target(1);
            let out = self.tick(Some(target), None);
            let decision = out.target_decision.clone().unwrap();
            let start = self.t_s();
            while self.cycle.phase() != CyclePhase::Idle && self.t_s() - start < max_s {
                self.tick(None, None);
            }
            decision
        }

        fn phase_durations(&self) -> Vec<(CyclePhase, f64)> {
            self.phase_log
                .windows(2)
                .map(|w| (w[0].0, w[1].1 - w[0].1))
                .skip(1)
                .collect()
        }

        fn event_kinds(&self) -> Vec<CycleEvent> {
            self.events.iter().map(|e| e.0).collect()
        }
    }

    /// A mid-workspace apple of arm 1, 0.52 m from the home end-effector position.
    const TYPICAL_APPLE_M: [f64; 3] = [1.45, -0.05, 0.50];

    #[test]
    fn cycle_timing_matches_the_fig_12_analysis() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        let decision = w.run_cycle(20.0);
        assert_eq!(decision, TargetDecision::Accepted { id: 1 });
        assert_eq!(
            w.event_kinds(),
            vec![
                CycleEvent::ApproachComplete,
                CycleEvent::Attached,
                CycleEvent::DetachComplete,
                CycleEvent::RetractComplete,
                CycleEvent::CycleComplete { harvested: true },
            ]
        );
        let durations = w.phase_durations();
        let phases: Vec<CyclePhase> = durations.iter().map(|d| d.0).collect();
        assert_eq!(
            phases,
            vec![
                CyclePhase::Approach,
                CyclePhase::Attach,
                CyclePhase::Retract,
                CyclePhase::Release
            ]
        );
        let d: Vec<f64> = durations.iter().map(|d| d.1).collect();
        let total: f64 = d.iter().sum();
        println!(
            "approach {:.3} s, attach {:.3} s, retract {:.3} s, release {:.3} s, total {total:.3} s, \
             max tracking error {:.1} mm",
            d[0],
            d[1],
            d[2],
            d[3],
            w.max_tracking_error_m * 1e3
        );
        // Fig. 12 (derived in CONTROLLER.md): arm movement ~2.0 s each way, attach + release
        // ~0.5 s, one cycle ~4.5 s.
        assert!((1.6..=2.4).contains(&d[0]), "approach {}", d[0]);
        assert!((1.6..=2.4).contains(&d[2]), "retract {}", d[2]);
        assert!((d[0] - d[2]).abs() < 0.3, "approach and retract differ");
        assert!(
            (0.3..=0.8).contains(&(d[1] + d[3])),
            "attach + release {}",
            d[1] + d[3]
        );
        assert!((4.0..=5.0).contains(&total), "cycle {total}");
        // The valve was open exactly from the end of the approach to the drop-off.
        let open: Vec<&CycleOutput> = w
            .outputs
            .iter()
            .filter(|o| o.valve_request == ValveRequest::Open)
            .collect();
        assert!(
            open.iter()
                .all(|o| matches!(o.phase, CyclePhase::Attach | CyclePhase::Retract))
        );
        assert!(w.outputs.iter().all(|o| !o.command.stopped));
        // Back home at the end.
        let home = forward(&ArmParams::arm1().links, &ArmParams::arm1().home);
        let ee = forward(&ArmParams::arm1().links, &w.servo.position);
        assert!(distance_m(home, ee) < 0.005);
    }

    #[test]
    fn failed_attachment_closes_the_valve_and_skips_release() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        w.sealable = false;
        w.run_cycle(20.0);
        assert_eq!(
            w.event_kinds(),
            vec![
                CycleEvent::ApproachComplete,
                CycleEvent::AttachFailed,
                CycleEvent::CycleComplete { harvested: false },
            ]
        );
        assert!(w.phase_log.iter().all(|p| p.0 != CyclePhase::Release));
        let failed = w
            .outputs
            .iter()
            .find(|o| o.event == Some(CycleEvent::AttachFailed))
            .unwrap();
        assert_eq!(failed.valve_request, ValveRequest::Closed);
        assert_eq!(failed.phase, CyclePhase::Retract);
    }

    #[test]
    fn apple_lost_during_retract_closes_the_valve_at_once() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        w.drop_apple_in_retract = true;
        w.run_cycle(20.0);
        let kinds = w.event_kinds();
        assert_eq!(
            kinds,
            vec![
                CycleEvent::ApproachComplete,
                CycleEvent::Attached,
                CycleEvent::DetachComplete,
                CycleEvent::AppleLost,
                CycleEvent::CycleComplete { harvested: false },
            ]
        );
        let lost = w
            .outputs
            .iter()
            .position(|o| o.event == Some(CycleEvent::AppleLost))
            .unwrap();
        assert_eq!(w.outputs[lost].valve_request, ValveRequest::Closed);
        assert!(
            w.outputs[lost..]
                .iter()
                .all(|o| o.valve_request == ValveRequest::Closed)
        );
        assert!(w.phase_log.iter().all(|p| p.0 != CyclePhase::Release));
    }

    #[test]
    fn valve_never_granted_times_out_and_retracts() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        w.valve_obeys = false;
        w.run_cycle(20.0);
        assert_eq!(
            w.event_kinds(),
            vec![
                CycleEvent::ApproachComplete,
                CycleEvent::ValveGrantTimeout,
                CycleEvent::CycleComplete { harvested: false },
            ]
        );
        let (_, t_complete) = w.events[0];
        let (_, t_timeout) = w.events[1];
        assert!(t_timeout - t_complete >= CycleConfig::default().valve_grant_timeout_s);
    }

    #[test]
    fn bad_targets_are_rejected_with_a_reason() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        w.tick(None, None);
        let now = w.now_ns;
        let reject = |w: &mut World, t: TargetRequest| match w.tick(Some(t), None).target_decision {
            Some(TargetDecision::Rejected(r)) => r,
            other => panic!("expected a rejection, got {other:?}"),
        };
        let base = TargetRequest {
            id: 7,
            position_m: TYPICAL_APPLE_M,
            detected_at_ns: now,
        };
        let r = reject(
            &mut w,
            TargetRequest {
                position_m: [f64::NAN, 0.0, 0.4],
                ..base
            },
        );
        assert!(matches!(r, TargetRejection::NonFinite { id: 7, .. }) && !r.is_retryable());
        let t = TargetRequest {
            detected_at_ns: w.now_ns - 3_000_000_000,
            ..base
        };
        let r = reject(&mut w, t);
        assert!(matches!(r, TargetRejection::Stale { .. }) && !r.is_retryable());
        let t = TargetRequest {
            detected_at_ns: w.now_ns + 1_000_000,
            ..base
        };
        let r = reject(&mut w, t);
        assert!(matches!(r, TargetRejection::FromFuture { .. }));
        let t = TargetRequest {
            position_m: [2.5, 0.11, 0.221],
            detected_at_ns: w.now_ns,
            ..base
        };
        let r = reject(&mut w, t);
        assert!(matches!(
            r,
            TargetRejection::Unreachable {
                reason: IkError::JointLimit { .. },
                ..
            }
        ));
        assert_eq!(w.cycle.phase(), CyclePhase::Idle);
        // Accept, then a different target while busy is refused (retryable); a repeat of the
        // current one is silently ignored.
        let ok = w.tick(
            Some(TargetRequest {
                detected_at_ns: w.now_ns,
                ..base
            }),
            None,
        );
        assert_eq!(ok.target_decision, Some(TargetDecision::Accepted { id: 7 }));
        assert_eq!(ok.goal_m, Some(TYPICAL_APPLE_M));
        let r = reject(&mut w, TargetRequest { id: 8, ..base });
        assert!(matches!(
            r,
            TargetRejection::Busy {
                id: 8,
                phase: CyclePhase::Approach
            }
        ));
        assert!(r.is_retryable());
        assert_eq!(w.tick(Some(base), None).target_decision, None);
    }

    #[test]
    fn clearance_against_the_other_arm() {
        let a1 = ArmParams::arm1();
        let a2 = ArmParams::arm2();
        let mut w = World::new(a1, a2, TYPICAL_APPLE_M);
        let other_home = forward(&a2.links, &a2.home);
        // Arm 2 idle at home: far enough.
        let idle = OtherArmState {
            phase: CyclePhase::Idle,
            end_effector_m: other_home,
            goal_m: None,
        };
        // Arm 2 heading across to the +y side, through arm 1's path.
        let crossing = OtherArmState {
            phase: CyclePhase::Approach,
            end_effector_m: other_home,
            goal_m: Some([1.40, 0.05, 0.45]),
        };
        let target = TargetRequest {
            id: 3,
            position_m: TYPICAL_APPLE_M,
            detected_at_ns: w.now_ns,
        };
        let out = w.tick(Some(target), Some(crossing));
        match out.target_decision {
            Some(TargetDecision::Rejected(r)) => {
                assert!(
                    matches!(r, TargetRejection::ClearanceConflict { .. }),
                    "{r}"
                );
                assert!(r.is_retryable());
            }
            other => panic!("expected a clearance conflict, got {other:?}"),
        }
        let unknown = OtherArmState {
            goal_m: None,
            ..crossing
        };
        let target = TargetRequest {
            detected_at_ns: w.now_ns,
            ..target
        };
        assert!(matches!(
            w.tick(Some(target), Some(unknown)).target_decision,
            Some(TargetDecision::Rejected(
                TargetRejection::OtherArmGoalUnknown { id: 3 }
            ))
        ));
        let target = TargetRequest {
            detected_at_ns: w.now_ns,
            ..target
        };
        assert_eq!(
            w.tick(Some(target), Some(idle)).target_decision,
            Some(TargetDecision::Accepted { id: 3 })
        );
    }

    #[test]
    fn stale_feedback_stops_the_arm_and_the_motion_resumes_afterwards() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        let target = w.target(1);
        w.tick(Some(target), None);
        for _ in 0..100 {
            w.tick(None, None);
        }
        w.feedback_delay_ns = 200_000_000;
        let out = w.tick(None, None);
        assert!(out.command.stopped);
        assert_eq!(out.command.velocity, JointVelocity::ZERO);
        assert!(matches!(
            out.event,
            Some(CycleEvent::FeedbackInvalid { .. })
        ));
        assert_eq!(out.phase, CyclePhase::Approach);
        for _ in 0..20 {
            w.tick(None, None);
        }
        w.feedback_delay_ns = 0;
        let start = w.t_s();
        while w.cycle.phase() != CyclePhase::Idle && w.t_s() - start < 20.0 {
            w.tick(None, None);
        }
        assert_eq!(
            w.events.last().map(|e| e.0),
            Some(CycleEvent::CycleComplete { harvested: true })
        );
    }

    #[test]
    fn no_motion_starts_without_fresh_feedback() {
        let mut w = World::new(ArmParams::arm1(), ArmParams::arm2(), TYPICAL_APPLE_M);
        w.feedback_delay_ns = 1_000_000_000;
        let target = w.target(9);
        let out = w.tick(Some(target), None);
        assert_eq!(
            out.target_decision,
            Some(TargetDecision::Rejected(TargetRejection::NoFeedback {
                id: 9
            }))
        );
        assert_eq!(out.phase, CyclePhase::Idle);
        assert!(out.command.stopped);
        w.feedback_delay_ns = 0;
        let target = w.target(9);
        assert_eq!(
            w.tick(Some(target), None).target_decision,
            Some(TargetDecision::Accepted { id: 9 })
        );
    }

    #[test]
    fn other_arm_state_mirrors_the_output() {
        let mut w = World::new(ArmParams::arm2(), ArmParams::arm1(), [1.35, -0.15, 0.35]);
        let target = w.target(5);
        let out = w.tick(Some(target), None);
        let other = OtherArmState::from_output(&out);
        assert_eq!(other.phase, CyclePhase::Approach);
        assert_eq!(other.goal_m, Some([1.35, -0.15, 0.35]));
        assert_eq!(other.end_effector_m, out.end_effector_m);
    }

    /// Both arms with a shared vacuum: the test plays the coordinator of eq. 11 (a valve opens
    /// only while the other arm is not attempting an attachment) and keeps offering each arm an
    /// apple whenever it is idle. With independent cycles and staggered attachments, two apples
    /// are released per single-arm cycle: the 2024 timeline of Fig. 12.
    #[test]
    fn two_arms_interleave_as_in_the_2024_timeline() {
        let (a1, a2) = (ArmParams::arm1(), ArmParams::arm2());
        let mut w1 = World::new(a1, a2, [1.45, 0.10, 0.50]);
        let mut w2 = World::new(a2, a1, [1.45, -0.12, 0.50]);
        w1.valve_obeys = false;
        w2.valve_obeys = false;
        let mut last2: Option<CycleOutput> = None;
        let mut next_id = 100;
        let mut releases = Vec::new();
        let mut clearance_refusals = 0;
        for _ in 0..(40.0 / 0.005) as usize {
            let offer1 = (w1.cycle.phase() == CyclePhase::Idle).then(|| w1.target(next_id));
            let other1 = last2.as_ref().map(OtherArmState::from_output);
            let out1 = w1.tick(offer1, other1);
            let offer2 = (w2.cycle.phase() == CyclePhase::Idle).then(|| w2.target(next_id + 1));
            let out2 = w2.tick(offer2, Some(OtherArmState::from_output(&out1)));
            for out in [&out1, &out2] {
                match &out.target_decision {
                    Some(TargetDecision::Accepted { .. }) => next_id += 2,
                    Some(TargetDecision::Rejected(TargetRejection::ClearanceConflict {
                        ..
                    })) => clearance_refusals += 1,
                    Some(TargetDecision::Rejected(r)) => panic!("unexpected rejection {r}"),
                    None => {}
                }
                if out.event == Some(CycleEvent::CycleComplete { harvested: true }) {
                    releases.push(w1.t_s());
                }
            }
            // Coordinator (eq. 11): a closed valve opens only while the other arm is not
            // attempting an attachment (open and nothing attached); an open valve stays open
            // while requested (a held apple seals its tube). Arm 1 wins ties.
            let attempting2 = w2.valve_open && !w2.attached;
            let open1 = out1.valve_request == ValveRequest::Open && (w1.valve_open || !attempting2);
            let attempting1 = open1 && !w1.attached;
            let open2 = out2.valve_request == ValveRequest::Open && (w2.valve_open || !attempting1);
            let both_attempting = open1 && open2 && !w1.attached && !w2.attached;
            assert!(!both_attempting, "both arms attempting an attachment");
            w1.valve_open = open1;
            w2.valve_open = open2;
            last2 = Some(out2);
        }
        assert!(
            releases.len() >= 14,
            "only {} apples in 40 s",
            releases.len()
        );
        let steady = &releases[2..];
        let per_apple_s = (steady[steady.len() - 1] - steady[0]) / (steady.len() - 1) as f64;
        println!(
            "two arms: {} apples in 40 s, {per_apple_s:.2} s per apple, {clearance_refusals} \
             clearance refusals",
            releases.len()
        );
        // Fig. 12, 2024 version: half the single-arm cycle (4.5 s -> 2.25 s per apple).
        assert!(
            (1.9..=2.6).contains(&per_apple_s),
            "{per_apple_s} s per apple"
        );
    }

    #[test]
    fn config_validates_and_round_trips() {
        assert_eq!(CycleConfig::default().validate(), Ok(()));
        let bad = CycleConfig {
            speed_fraction: 0.0,
            ..CycleConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(CycleConfigError::Invalid {
                field: "speed_fraction",
                ..
            })
        ));
        let bad = CycleConfig {
            release_dwell_s: f64::NAN,
            ..CycleConfig::default()
        };
        assert!(PickingCycle::new(ArmParams::arm1(), ArmParams::arm2(), bad).is_err());
        let text = toml::to_string(&CycleConfig::default()).unwrap();
        let back: CycleConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, CycleConfig::default());
        assert!(toml::from_str::<CycleConfig>(&format!("{text}\nbogus = 1\n")).is_err());
    }
}
