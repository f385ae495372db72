//! The Retract phase: back to the drop-off pose, with suction held while an apple is held; an
//! apple lost on the way closes the valve at once (eq. 11).

use tracing::warn;

use super::motion::{Motion, MotionProgress};
use super::state::{ReleaseStage, State, Transition};
use super::{CycleEvent, CycleInput, PickingCycle};
use harvest_robot_model::kinematics::forward;

impl PickingCycle {
    /// The retract to home, first pulling straight back by the approach standoff so the path
    /// mirrors the approach; `apple` tells whether an apple is held (without one the valve
    /// closes, see `State::valve_request`).
    pub(super) fn retract(&self, input: &CycleInput, target_id: u64, apple: bool) -> State {
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
        State::Retract {
            motion,
            target_id,
            apple,
        }
    }

    /// The Retract step: an apple lost on the way closes the valve at once (the motion goes
    /// on without it); at the drop-off, an apple held goes on to Release, otherwise the cycle
    /// ends unharvested.
    pub(super) fn step_retract(
        &self,
        motion: &Motion,
        target_id: u64,
        apple: bool,
        input: &CycleInput,
    ) -> Transition {
        if apple && !input.apple_attached {
            warn!(arm = %self.params.arm, id = target_id, "apple lost during retract");
            return Transition::to(
                State::Retract {
                    motion: motion.clone(),
                    target_id,
                    apple: false,
                },
                CycleEvent::AppleLost,
            );
        }
        match self.progress(motion, input) {
            MotionProgress::Running => Transition::Stay,
            MotionProgress::Arrived | MotionProgress::TimedOut if apple => Transition::to(
                State::Release {
                    target_id,
                    stage: ReleaseStage::WaitingValveClosed {
                        since_ns: input.now_ns,
                    },
                },
                CycleEvent::RetractComplete,
            ),
            MotionProgress::Arrived | MotionProgress::TimedOut => {
                Transition::to(State::Idle, CycleEvent::CycleComplete { harvested: false })
            }
        }
    }
}
