//! The Release phase: at the drop-off, wait for the valve to report closed, then let the apple
//! fall for the release dwell; the cycle ends harvested.

use tracing::warn;

use super::motion::elapsed_s;
use super::state::{ReleaseStage, State, Transition};
use super::{CycleEvent, CycleInput, PickingCycle};

impl PickingCycle {
    /// The Release step for its current `stage`.
    pub(super) fn step_release(
        &self,
        target_id: u64,
        stage: &ReleaseStage,
        input: &CycleInput,
    ) -> Transition {
        let now = input.now_ns;
        match *stage {
            ReleaseStage::WaitingValveClosed { since_ns } => {
                if !input.valve_open {
                    Transition::quietly(State::Release {
                        target_id,
                        stage: ReleaseStage::Dropping { since_ns: now },
                    })
                } else if elapsed_s(now, since_ns) > self.config.valve_grant_timeout_s {
                    warn!(arm = %self.params.arm, id = target_id, "valve did not close");
                    Transition::to(State::Idle, CycleEvent::ValveCloseTimeout)
                } else {
                    Transition::Stay
                }
            }
            ReleaseStage::Dropping { since_ns } => {
                if elapsed_s(now, since_ns) >= self.config.release_dwell_s {
                    Transition::to(State::Idle, CycleEvent::CycleComplete { harvested: true })
                } else {
                    Transition::Stay
                }
            }
        }
    }
}
