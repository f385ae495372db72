//! Step 3: each arm's attempt followed from its published state: a dispatched target taken up,
//! timed out, refused, or withdrawn after waiting too long for the other arm; an attempt that
//! ends harvested or failed.

use tracing::{debug, info, warn};

use super::arm_track::{Dispatch, Withdrawal};
use super::{VacuumNode, VacuumNodeEvent, VacuumNodeInput, wire_id};
use crate::assignment::AppleId;
use crate::replan::AttemptResult;
use harvest_ipc::Header;
use harvest_ipc::payloads::arm::TargetStatus;
use harvest_ipc::payloads::{ArmPhase as PhaseCode, ArmState, ArmTarget};
use harvest_robot_model::ArmId;

impl VacuumNode {
    /// Step 3: follow each arm's attempt from its published state.
    pub(super) fn track_attempts(&mut self, input: &VacuumNodeInput<'_>, now_ns: u64) {
        let timeout_ns = (self.config.dispatch_timeout_s * 1e9) as u64;
        for arm in ArmId::ALL {
            let i = arm.index();
            let state = input.arm_states[i];
            let phase = state.and_then(|s| s.phase.get().ok());
            if matches!(phase, Some(PhaseCode::Idle | PhaseCode::Approach)) {
                self.arms[i].opened_in_cycle = false;
            }
            if let Some(d) = self.arms[i].dispatched {
                let taken = state.is_some_and(|s| {
                    s.apple_id == wire_id(d.apple.id) && phase.is_some_and(|p| p != PhaseCode::Idle)
                });
                if taken {
                    self.arms[i].dispatched = None;
                    self.arms[i].withdrawn = None;
                    self.arms[i].sealed_peak_mmh2o = 0.0;
                    self.arms[i].seal_lost_after_mmh2o = None;
                    self.arms[i].active = Some(d);
                    debug!(%arm, apple = d.apple.id.0, "attempt started");
                    self.output.events.push(VacuumNodeEvent::AttemptStarted {
                        arm,
                        apple: d.apple.id,
                    });
                } else {
                    if let Some(status) = state
                        .filter(|s| s.target_apple_id == wire_id(d.apple.id))
                        .and_then(|s| s.target_status.get().ok())
                        && status != TargetStatus::None
                    {
                        self.on_target_status(arm, d, status, now_ns);
                    }
                    // Still dispatched (waiting with nowhere else to go, or no report).
                    let still = self.arms[i].dispatched.is_some();
                    if still && now_ns.saturating_sub(d.at_ns) > timeout_ns {
                        self.arms[i].dispatched = None;
                        self.planner.finish(arm, AttemptResult::Failed);
                        self.remember(&d.apple.position_m);
                        warn!(%arm, apple = d.apple.id.0, "target not taken up: given up");
                        self.output.events.push(VacuumNodeEvent::DispatchTimedOut {
                            arm,
                            apple: d.apple.id,
                        });
                    }
                }
            }
            if self.arms[i].active.is_none()
                && let Some(Withdrawal { apple: id, .. }) = self.arms[i].withdrawn
                && let Some(s) = state
                && s.apple_id == wire_id(id)
                && phase.is_some_and(|p| p != PhaseCode::Idle && p != PhaseCode::Stopped)
            {
                self.adopt(arm, id, s, now_ns);
            }
            if let Some(d) = self.arms[i].active {
                let over = state.is_none_or(|s| {
                    s.apple_id != wire_id(d.apple.id) || phase == Some(PhaseCode::Idle)
                });
                if over {
                    let harvested = state.is_some_and(|s| s.harvested_count > d.harvested_before);
                    let result = if harvested {
                        AttemptResult::Harvested
                    } else {
                        AttemptResult::Failed
                    };
                    self.arms[i].active = None;
                    self.planner.finish(arm, result);
                    let threshold = self.config.slip_give_up_vacuum_mmh2o;
                    match self.arms[i].seal_lost_after_mmh2o.take() {
                        Some(peak)
                            if result == AttemptResult::Failed
                                && threshold > 0.0
                                && peak >= threshold =>
                        {
                            // The stem held against (nearly) the full force of the cup:
                            // another attempt would fail the same way.
                            info!(%arm, apple = d.apple.id.0, peak_mmh2o = peak, "slipped at full vacuum: apple given up");
                            self.give_up(&d.apple.position_m);
                        }
                        _ => {
                            self.remember(&d.apple.position_m);
                        }
                    }
                    debug!(%arm, apple = d.apple.id.0, ?result, "attempt finished");
                    self.output.events.push(VacuumNodeEvent::AttemptFinished {
                        arm,
                        apple: d.apple.id,
                        result,
                    });
                }
            }
        }
    }

    /// A dispatched target the arm reports refused (for good, or for the moment).
    fn on_target_status(&mut self, arm: ArmId, d: Dispatch, status: TargetStatus, now_ns: u64) {
        let i = arm.index();
        if status == TargetStatus::Refused {
            self.arms[i].dispatched = None;
            self.planner.finish(arm, AttemptResult::Failed);
            self.remember(&d.apple.position_m);
            warn!(%arm, apple = d.apple.id.0, "target refused by the arm");
            self.output.events.push(VacuumNodeEvent::TargetRefused {
                arm,
                apple: d.apple.id,
            });
            return;
        }
        let patience_ns = (self.config.waiting_patience_s * 1e9) as u64;
        if now_ns.saturating_sub(d.at_ns) < patience_ns {
            return;
        }
        let other = arm.other();
        let radius_m = self.radius_of(&d.apple.position_m);
        let to = if self.config.arms_enabled[other.index()]
            && (self.reachable)(other, &d.apple.position_m, radius_m)
        {
            other
        } else if !self.planner.queue(arm).is_empty() {
            arm
        } else {
            // Nowhere else to go: the arm keeps retrying until it can go or the dispatch
            // times out.
            return;
        };
        if self.planner.take_back(arm, to).is_none() {
            return;
        }
        let track = &mut self.arms[i];
        track.dispatched = None;
        track.withdrawn = Some(Withdrawal {
            apple: d.apple.id,
            position_m: d.apple.position_m,
            at_ns: now_ns,
            to_other: to == other,
        });
        track.last_target = None;
        // Overwritten by the arm's next apple if one is dispatched this tick.
        self.output.targets[i] = Some(self.withdrawal_target(i, now_ns));
        debug!(%arm, apple = d.apple.id.0, %to, "target withdrawn: the arm waits for the other arm");
        self.output.events.push(VacuumNodeEvent::TargetWithdrawn {
            arm,
            apple: d.apple.id,
            to,
        });
    }

    /// The next target for arm `i` that withdraws the one it has not taken up (apple id 0, NaN
    /// position: an arm without withdrawals rejects it as not finite, with the same effect).
    fn withdrawal_target(&mut self, i: usize, now_ns: u64) -> ArmTarget {
        self.target_seq += 1;
        ArmTarget {
            header: Header {
                msg_seq: self.target_seq,
                capture_ns: now_ns,
                publish_ns: 0,
            },
            arm_id: i as u8 + 1,
            _reserved: [0; 3],
            apple_id: 0,
            position_in_robot_m: [f64::NAN; 3],
            radius_m: f64::NAN,
            source_capture_ns: self.last_set_capture_ns,
        }
    }

    /// The arm took up the apple withdrawn from it (the withdrawal crossed its acceptance):
    /// follow that attempt; a target dispatched since is taken back to the arm's own queue
    /// and withdrawn.
    fn adopt(&mut self, arm: ArmId, id: AppleId, state: &ArmState, now_ns: u64) {
        let i = arm.index();
        self.arms[i].withdrawn = None;
        if self.arms[i].dispatched.take().is_some() {
            self.planner.take_back(arm, arm);
            self.output.targets[i] = Some(self.withdrawal_target(i, now_ns));
        }
        let Some(apple) = self.planner.adopt(arm, id) else {
            warn!(%arm, apple = id.0, "arm took up a withdrawn apple that is no longer waiting");
            return;
        };
        self.arms[i].active = Some(Dispatch {
            apple,
            at_ns: now_ns,
            harvested_before: state.harvested_count,
        });
        info!(%arm, apple = id.0, "arm took up a withdrawn target: attempt followed");
        self.output
            .events
            .push(VacuumNodeEvent::AttemptStarted { arm, apple: id });
    }
}
