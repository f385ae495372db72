//! Steps 4 to 6, the interlock and the emergency stop: the policy's force-closes, the arms' standing valve
//! requests answered (oldest waiter first), and every valve closed on an emergency stop.

use tracing::{debug, warn};

use super::arm_track::ArmTrack;
use super::{
    REFUSED_ARM_DISABLED, VacuumNode, VacuumNodeEvent, VacuumNodeInput, ValveCloseCause,
    refuse_reason_code,
};
use crate::policy::{Decision, RefuseReason, Request, ValveOrder};
use crate::pressure::AttachmentState;
use crate::replan::AttemptResult;
use harvest_ipc::Header;
use harvest_ipc::payloads::{ValveGrant, ValveRequest, ValveRequestKind};
use harvest_robot_model::ArmId;

impl VacuumNode {
    pub(super) fn emergency_stop(&mut self) {
        if !self.stopped {
            self.stopped = true;
            self.output.close_all = true;
            warn!("emergency stop: closing every valve");
            self.output
                .events
                .push(VacuumNodeEvent::EmergencyStop { engaged: true });
            for arm in ArmId::ALL {
                let track = &mut self.arms[arm.index()];
                if track.valve_open {
                    track.valve_open = false;
                    self.output.events.push(VacuumNodeEvent::ValveClosed {
                        arm,
                        cause: ValveCloseCause::EmergencyStop,
                    });
                }
                let apple = track.dispatched.take().or(track.active.take());
                if let Some(d) = apple {
                    self.planner.finish(arm, AttemptResult::Failed);
                    self.output.events.push(VacuumNodeEvent::AttemptFinished {
                        arm,
                        apple: d.apple.id,
                        result: AttemptResult::Failed,
                    });
                }
            }
        }
    }

    /// Steps 4 and 6: the policy's force-closes.
    pub(super) fn supervise(&mut self, input: &VacuumNodeInput<'_>) {
        let orders = self.policy.supervise(&self.pair(input));
        for arm in ArmId::ALL {
            if let ValveOrder::ForceClose(reason) = orders[arm.index()]
                && self.arms[arm.index()].valve_open
            {
                self.arms[arm.index()].valve_open = false;
                debug!(%arm, %reason, "valve force-closed by the policy");
                self.output.events.push(VacuumNodeEvent::ValveClosed {
                    arm,
                    cause: ValveCloseCause::Policy(reason),
                });
            }
        }
    }

    /// Step 6, the interlock's second rule (module docs): both valves open, neither cup sealed.
    pub(super) fn interlock(&mut self) {
        let unsealed_open = |node: &Self, arm: ArmId| {
            node.arms[arm.index()].valve_open
                && node.inference.state(arm) != AttachmentState::Sealed
        };
        if !ArmId::ALL.iter().all(|&arm| unsealed_open(self, arm)) {
            return;
        }
        let failed = ArmId::ALL.map(|arm| {
            matches!(
                self.inference.state(arm),
                AttachmentState::AttachFailed | AttachmentState::Dropped
            )
        });
        let close = if failed.iter().any(|&f| f) {
            failed
        } else if self.arms[1].opened_at_ns >= self.arms[0].opened_at_ns {
            [false, true]
        } else {
            [true, false]
        };
        for arm in ArmId::ALL {
            if close[arm.index()] {
                self.arms[arm.index()].valve_open = false;
                warn!(%arm, "interlock: both valves open with neither cup sealed; valve closed");
                self.output.events.push(VacuumNodeEvent::ValveClosed {
                    arm,
                    cause: ValveCloseCause::Interlock,
                });
            }
        }
    }

    /// Step 5: the arms' standing valve requests.
    pub(super) fn answer_requests(&mut self, input: &VacuumNodeInput<'_>, now_ns: u64) {
        let mut order = ArmId::ALL;
        for arm in ArmId::ALL {
            let track = &mut self.arms[arm.index()];
            match input.valve_requests[arm.index()] {
                Some(r) if r.kind == ValveRequestKind::OpenForAttach => {
                    if track.open_request_since_ns.map(|(seq, _)| seq) != Some(r.request_seq) {
                        track.open_request_since_ns = Some((r.request_seq, now_ns));
                    }
                }
                _ => track.open_request_since_ns = None,
            }
        }
        let since = |track: &ArmTrack| track.open_request_since_ns.map_or(u64::MAX, |(_, t)| t);
        if since(&self.arms[1]) < since(&self.arms[0]) {
            order = [ArmId::Arm2, ArmId::Arm1];
        }
        for arm in order {
            let i = arm.index();
            let Some(request) = input.valve_requests[i] else {
                continue;
            };
            if request.arm_id != arm.index() as u8 + 1 {
                continue;
            }
            // An unknown request kind is taken as a request to close (the safe side).
            match request.kind.get() {
                Ok(ValveRequestKind::Close) | Err(_) => {
                    if self.arms[i].valve_open {
                        self.arms[i].valve_open = false;
                        debug!(%arm, "valve closed on the arm's request");
                        self.output.events.push(VacuumNodeEvent::ValveClosed {
                            arm,
                            cause: ValveCloseCause::ArmRequest,
                        });
                    }
                }
                Ok(ValveRequestKind::OpenForAttach) => self.answer_open(input, arm, request),
            }
        }
    }

    fn answer_open(&mut self, input: &VacuumNodeInput<'_>, arm: ArmId, request: &ValveRequest) {
        let i = arm.index();
        let track = self.arms[i];
        if track.valve_open || track.granted_seq == Some(request.request_seq) {
            return;
        }
        let other = arm.other();
        // The interlock (module docs): only this node's valves and pressures, no arm report.
        let beside_unsealed = self.arms[other.index()].valve_open
            && self.inference.state(other) != AttachmentState::Sealed;
        let (code, reason) = if !self.config.arms_enabled[i] {
            (REFUSED_ARM_DISABLED, None)
        } else if beside_unsealed {
            let reason = RefuseReason::OtherArmAttempting;
            (refuse_reason_code(&reason), Some(reason))
        } else {
            match self
                .policy
                .decide(arm, Request::OpenValve, &self.pair(input))
            {
                Decision::Grant => {
                    let track = &mut self.arms[i];
                    track.valve_open = true;
                    track.opened_at_ns = input.now_ns;
                    track.opened_in_cycle = true;
                    track.granted_seq = Some(request.request_seq);
                    track.refused = None;
                    debug!(%arm, request_seq = request.request_seq, "valve opened");
                    self.output
                        .events
                        .push(VacuumNodeEvent::ValveOpened { arm });
                    self.output.grants[i] = Some(self.grant(input.now_ns, arm, request, 0));
                    return;
                }
                Decision::Refuse(reason) => (refuse_reason_code(&reason), Some(reason)),
            }
        };
        if self.arms[i].refused != Some((request.request_seq, code)) {
            self.arms[i].refused = Some((request.request_seq, code));
            debug!(%arm, code, ?reason, "valve request refused");
            self.output
                .events
                .push(VacuumNodeEvent::ValveRefused { arm, reason });
            self.output.grants[i] = Some(self.grant(input.now_ns, arm, request, code));
        }
    }

    fn grant(&mut self, now_ns: u64, arm: ArmId, request: &ValveRequest, code: u8) -> ValveGrant {
        self.grant_seq += 1;
        ValveGrant {
            header: Header {
                msg_seq: self.grant_seq,
                capture_ns: now_ns,
                publish_ns: 0,
            },
            arm_id: arm.index() as u8 + 1,
            granted: u8::from(code == 0),
            reason: code,
            _reserved: 0,
            request_seq: request.request_seq,
        }
    }
}
