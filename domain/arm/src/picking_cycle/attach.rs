//! The Attach phase (the paper's Detach): at the apple, wait for the valve to open, then for the
//! pressure-confirmed attachment, then twist the end-effector; any failure retracts without the
//! apple and so closes the valve at once (Fig. 9, failure branch).

use tracing::warn;

use super::motion::{MotionProgress, elapsed_s};
use super::state::{AttachStage, State, Transition};
use super::{CycleEvent, CycleInput, PickingCycle, TargetRequest};
use harvest_robot_model::joint::JointPosition;

impl PickingCycle {
    /// The Attach step for its current `stage`.
    pub(super) fn step_attach(
        &self,
        target: &TargetRequest,
        hold: &JointPosition,
        stage: &AttachStage,
        input: &CycleInput,
    ) -> Transition {
        let now = input.now_ns;
        let cfg = &self.config;
        let attach = |stage| State::Attach {
            target: *target,
            hold: *hold,
            stage,
        };
        match stage {
            AttachStage::WaitingValve { since_ns } => {
                if input.valve_open {
                    Transition::quietly(attach(AttachStage::WaitingAttachment { since_ns: now }))
                } else if elapsed_s(now, *since_ns) > cfg.valve_grant_timeout_s {
                    warn!(arm = %self.params.arm, id = target.id, "valve not granted");
                    Transition::to(
                        self.retract(input, target.id, false),
                        CycleEvent::ValveGrantTimeout,
                    )
                } else {
                    Transition::Stay
                }
            }
            AttachStage::WaitingAttachment { since_ns } => {
                if input.apple_attached {
                    let twist_goal = input.joints.with_twist(cfg.detach_twist_rad);
                    let twist_goal = self.params.position_limits.clamp(&twist_goal);
                    let motion = self.motion_to(input, twist_goal);
                    Transition::to(
                        attach(AttachStage::Twisting { motion }),
                        CycleEvent::Attached,
                    )
                } else if elapsed_s(now, *since_ns) > cfg.attach_timeout_s {
                    warn!(arm = %self.params.arm, id = target.id, "attachment failed");
                    Transition::to(
                        self.retract(input, target.id, false),
                        CycleEvent::AttachFailed,
                    )
                } else {
                    Transition::Stay
                }
            }
            AttachStage::Twisting { motion } => {
                if !input.apple_attached {
                    warn!(arm = %self.params.arm, id = target.id, "apple lost while twisting");
                    return Transition::to(
                        self.retract(input, target.id, false),
                        CycleEvent::AppleLost,
                    );
                }
                match self.progress(motion, input) {
                    MotionProgress::Running => Transition::Stay,
                    MotionProgress::Arrived | MotionProgress::TimedOut => Transition::to(
                        self.retract(input, target.id, true),
                        CycleEvent::DetachComplete,
                    ),
                }
            }
        }
    }
}
