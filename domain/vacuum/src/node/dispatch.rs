//! Step 7: at most one target per tick, to the idle arm that got one least recently, when the
//! policy grants it the approach.

use tracing::debug;

use super::arm_track::Dispatch;
use super::{VacuumNode, VacuumNodeEvent, VacuumNodeInput, refuse_reason_code, wire_id};
use crate::policy::{Decision, Request};
use harvest_ipc::Header;
use harvest_ipc::payloads::{ArmPhase as PhaseCode, ArmTarget};
use harvest_robot_model::ArmId;

impl VacuumNode {
    /// Step 7: at most one target per tick, to the idle arm that got one least recently.
    pub(super) fn dispatch(&mut self, input: &VacuumNodeInput<'_>, now_ns: u64) {
        let mut order = ArmId::ALL;
        if self.arms[1].last_dispatch_ns < self.arms[0].last_dispatch_ns {
            order = [ArmId::Arm2, ArmId::Arm1];
        }
        for arm in order {
            let i = arm.index();
            let Some(state) = input.arm_states[i] else {
                continue;
            };
            if self.dispatch_held[i] {
                continue;
            }
            let track = self.arms[i];
            let idle = state.phase == PhaseCode::Idle
                && track.dispatched.is_none()
                && track.active.is_none()
                && self.planner.in_progress(arm).is_none();
            if self.config.arms_enabled[i] && idle && self.planner.queue(arm).is_empty() {
                self.rebalance_for(arm, now_ns);
            }
            if !self.config.arms_enabled[i] || !idle || self.planner.queue(arm).is_empty() {
                continue;
            }
            let backoff_ns = (self.config.withdrawal_backoff_s * 1e9) as u64;
            if let Some(w) = self.arms[i].withdrawn
                && now_ns.saturating_sub(w.at_ns) < backoff_ns
                && self
                    .planner
                    .queue(arm)
                    .first()
                    .is_some_and(|a| a.id == w.apple)
            {
                continue;
            }
            match self
                .policy
                .decide(arm, Request::StartApproach, &self.pair(input))
            {
                Decision::Grant => {
                    let Some(apple) = self.planner.start_next(arm) else {
                        continue;
                    };
                    let radius_m = self.radius_of(&apple.position_m);
                    self.target_seq += 1;
                    let target = ArmTarget {
                        header: Header {
                            msg_seq: self.target_seq,
                            capture_ns: now_ns,
                            publish_ns: 0,
                        },
                        arm_id: i as u8 + 1,
                        _reserved: [0; 3],
                        apple_id: wire_id(apple.id),
                        position_in_robot_m: apple.position_m,
                        radius_m,
                        source_capture_ns: self.last_set_capture_ns,
                    };
                    let track = &mut self.arms[i];
                    track.dispatched = Some(Dispatch {
                        apple,
                        at_ns: now_ns,
                        harvested_before: state.harvested_count,
                    });
                    track.last_dispatch_ns = now_ns;
                    track.last_target = Some(target);
                    track.approach_refusal = None;
                    debug!(%arm, apple = apple.id.0, position_m = ?apple.position_m,
                        "target dispatched");
                    self.output.targets[i] = Some(target);
                    self.output
                        .events
                        .push(VacuumNodeEvent::TargetDispatched { arm, target });
                    return;
                }
                Decision::Refuse(reason) => {
                    let code = refuse_reason_code(&reason);
                    if self.arms[i].approach_refusal != Some(code) {
                        self.arms[i].approach_refusal = Some(code);
                        self.output
                            .events
                            .push(VacuumNodeEvent::ApproachRefused { arm, reason });
                    }
                }
            }
        }
    }
}
