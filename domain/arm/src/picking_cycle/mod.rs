//! The picking cycle of one arm as a plain state machine ([dual-arm sec. 3.3, Fig. 9a]):
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
//!
//! Layout: the types the callers see (`phase`, `input`, `output`, `event`, `target_decision`,
//! `config`); the internal `state` with the `Transition` a phase's step
//! returns; one file per phase that moves (`approach`, `attach`, `retract`, `release`), each
//! reading the current state and returning the transition, which [`PickingCycle::step`] applies;
//! `motion` (planning and arrival) and `clearance` (the check against the other arm).

mod approach;
mod attach;
mod clearance;
mod config;
mod event;
mod input;
mod motion;
mod output;
mod phase;
mod release;
mod retract;
mod state;
mod target_decision;

pub use config::{CycleConfig, CycleConfigError};
pub use event::CycleEvent;
pub use input::{CycleInput, OtherArmState, TargetRequest};
pub use output::{CycleOutput, ValveRequest};
pub use phase::CyclePhase;
pub use target_decision::{TargetDecision, TargetRejection};

use tracing::{debug, trace, warn};

use crate::controller::{JointCommand, TrackingController, TrackingReference};
use harvest_robot_model::kinematics::forward;
use harvest_robot_model::params::ArmParams;
use motion::elapsed_s;
use state::{AttachStage, State, Transition};

/// The picking cycle of one arm.
#[derive(Debug, Clone, PartialEq)]
pub struct PickingCycle {
    params: ArmParams,
    other_params: ArmParams,
    config: CycleConfig,
    controller: TrackingController,
    state: State,
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
        let gap_ns = self
            .last_now_ns
            .map_or(0, |last| input.now_ns.saturating_sub(last));
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
        // Compared in whole nanoseconds: 3 x 5 ms is exactly on the bound, not above it.
        let max_gap_ns =
            (self.config.max_tick_gap_periods * self.config.nominal_period_s * 1e9).round() as u64;
        if gap_ns > max_gap_ns {
            warn!(
                arm = %self.params.arm,
                gap_s = dt_s,
                max_gap_ms = max_gap_ns / 1_000_000,
                "control step late (deadline missed): stopping the arm"
            );
            return self.hold(
                input,
                CycleEvent::DeadlineMissed { gap_s: dt_s },
                end_effector_m,
            );
        }
        if !input.joints.is_finite() || feedback_age_s > self.config.max_feedback_age_s {
            warn!(
                arm = %self.params.arm,
                feedback_age_s,
                "joint feedback invalid or stale: stopping the arm"
            );
            return self.hold(
                input,
                CycleEvent::FeedbackInvalid {
                    age_s: feedback_age_s,
                },
                end_effector_m,
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

    /// The safe hold of a step that cannot be trusted (stale or invalid feedback, a late step):
    /// the arm is stopped, a running motion restarts from where the arm is on the next good
    /// step, a target offered while idle is refused for the moment (retried) after stale
    /// feedback and left undecided after a late step (offered again next step).
    fn hold(
        &mut self,
        input: &CycleInput,
        event: CycleEvent,
        end_effector_m: [f64; 3],
    ) -> CycleOutput {
        self.needs_replan = !matches!(self.state, State::Idle);
        let decision = match input.target {
            Some(t) if matches!(self.state, State::Idle) => match event {
                CycleEvent::FeedbackInvalid { .. } => {
                    Some(TargetDecision::Rejected(TargetRejection::NoFeedback {
                        id: t.id,
                    }))
                }
                _ => None,
            },
            Some(t) => self.busy_or_repeat(&t),
            None => None,
        };
        self.output(
            JointCommand::STOP,
            decision,
            Some(event),
            end_effector_m,
            None,
        )
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
            valve_request: self.state.valve_request(),
            target_decision,
            event,
            end_effector_m,
            goal_m,
            reference,
            target_id: self.state.target_id(),
        }
    }

    /// Runs the step of the current phase and applies the transition it returns: the one place
    /// where stepping changes the state. At most one event.
    fn advance(&mut self, input: &CycleInput) -> Option<CycleEvent> {
        let transition = match &self.state {
            State::Idle => Transition::Stay,
            State::Approach { motion, target } => self.step_approach(motion, target, input),
            State::Attach {
                target,
                hold,
                stage,
            } => self.step_attach(target, hold, stage, input),
            State::Retract {
                motion,
                target_id,
                apple,
            } => self.step_retract(motion, *target_id, *apple, input),
            State::Release { target_id, stage } => self.step_release(*target_id, stage, input),
        };
        match transition {
            Transition::Stay => None,
            Transition::To { state, event } => {
                self.state = state;
                event
            }
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
mod tests;
