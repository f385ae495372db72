//! The Approach phase: a target offered while idle is checked and planned (through a standoff
//! point short of the apple); the phase ends at the apple (on to Attach) or, when the arm does
//! not settle there, with a retract.

use tracing::{debug, warn};

use super::motion::{Motion, MotionProgress, elapsed_s};
use super::state::{AttachStage, State, Transition};
use super::{CycleEvent, CycleInput, PickingCycle, TargetDecision, TargetRejection, TargetRequest};
use crate::trajectory::JointTrajectory;
use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::kinematics::{forward, inverse};

impl PickingCycle {
    /// Decision for a target offered while busy: none for a repeat of the current target.
    pub(super) fn busy_or_repeat(&self, target: &TargetRequest) -> Option<TargetDecision> {
        if self.state.target_id() == Some(target.id) {
            return None;
        }
        Some(TargetDecision::Rejected(TargetRejection::Busy {
            id: target.id,
            phase: self.state.phase(),
        }))
    }

    /// Validates a target offered while idle and starts the approach if it passes.
    pub(super) fn offer(&mut self, target: &TargetRequest, input: &CycleInput) -> TargetDecision {
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

    /// Checks the target (finite, fresh, reachable, clear of the other arm) and plans the
    /// approach to it.
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

    /// The point `approach_standoff_m` short of `position_m` along -x, as joints, when it is
    /// reachable and lies ahead of `from_m` in x (otherwise the detour is skipped).
    pub(super) fn standoff(&self, position_m: [f64; 3], from_m: [f64; 3]) -> Option<JointPosition> {
        let standoff_m = self.config.approach_standoff_m;
        let [x, y, z] = position_m;
        let point = [x - standoff_m, y, z];
        (standoff_m > 0.0 && from_m[0] < point[0])
            .then(|| inverse(&self.params, point).ok())
            .flatten()
    }

    /// The Approach step: stay while moving; at the apple, hold there and wait for the valve
    /// (Attach); when the arm does not settle at the apple in time, retract without it.
    pub(super) fn step_approach(
        &self,
        motion: &Motion,
        target: &TargetRequest,
        input: &CycleInput,
    ) -> Transition {
        match self.progress(motion, input) {
            MotionProgress::Running => Transition::Stay,
            MotionProgress::Arrived => Transition::to(
                State::Attach {
                    target: *target,
                    hold: motion.goal,
                    stage: AttachStage::WaitingValve {
                        since_ns: input.now_ns,
                    },
                },
                CycleEvent::ApproachComplete,
            ),
            MotionProgress::TimedOut => {
                warn!(arm = %self.params.arm, id = target.id, "approach did not settle");
                Transition::to(
                    self.retract(input, target.id, false),
                    CycleEvent::ApproachTimeout,
                )
            }
        }
    }
}
