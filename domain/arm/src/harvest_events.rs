//! The arm's node events as `harvest/events` messages ([`HarvestEvent`]): what the arm process
//! publishes so that `harvest up` can print per-apple lines and summarize the harvest, and so
//! that refused targets (outside the workspace, NaN, stale) are reported with a reason.

use harvest_ipc::FixedString;
use harvest_ipc::payloads::harvest_event::HARVEST_EVENT_REASON_BYTES;
use harvest_ipc::payloads::{
    ArmPhase as PhaseCode, ArmTarget, HarvestCause, HarvestEvent, HarvestEventKind,
    HarvestEventSource,
};

/// The reason text of an event, formatted in place (the conversion runs in the control tick and
/// allocates nothing).
type Reason = FixedString<HARVEST_EVENT_REASON_BYTES>;

use crate::node::{ArmNodeEvent, AttemptFailure};
use crate::picking_cycle::{CycleEvent, TargetRejection};
use harvest_robot_model::params::ArmId;

/// The harvest cause of an arm's account of a failed attempt.
pub fn failure_cause(failure: AttemptFailure) -> HarvestCause {
    match failure {
        AttemptFailure::ApproachTimeout => HarvestCause::ApproachTimeout,
        AttemptFailure::ValveNotGranted => HarvestCause::ValveNotGranted,
        AttemptFailure::NoAttachment => HarvestCause::NoAttachment,
        AttemptFailure::AppleLost => HarvestCause::AppleLost,
        AttemptFailure::ValveNotClosed => HarvestCause::ValveNotClosed,
        AttemptFailure::EmergencyStop => HarvestCause::EmergencyStop,
    }
}

/// The harvest cause of a target refusal.
pub fn rejection_cause(rejection: &TargetRejection) -> HarvestCause {
    match rejection {
        TargetRejection::NonFinite { .. } => HarvestCause::NonFinite,
        TargetRejection::Stale { .. } => HarvestCause::Stale,
        TargetRejection::FromFuture { .. } => HarvestCause::FromFuture,
        TargetRejection::Unreachable { .. } => HarvestCause::OutsideWorkspace,
        TargetRejection::Busy { .. } => HarvestCause::Busy,
        TargetRejection::ClearanceConflict { .. } => HarvestCause::ClearanceConflict,
        TargetRejection::OtherArmGoalUnknown { .. } => HarvestCause::OtherArmGoalUnknown,
        TargetRejection::NoFeedback { .. } => HarvestCause::NoFeedback,
        TargetRejection::OtherArmPoseUnknown { .. } | TargetRejection::Planning { .. } => {
            HarvestCause::Other
        }
    }
}

/// Turns one arm's node events into harvest events, keeping track of the target the arm is
/// working on (from its acceptance to the end of the attempt) so that every event names its
/// apple and position.
///
/// The picking cycle reports invalid feedback on every tick it lasts; only its start is
/// published (call [`ArmEventReporter::end_tick`] after each tick's events).
#[derive(Debug, Clone)]
pub struct ArmEventReporter {
    number: u8,
    source: HarvestEventSource,
    current: Option<ArmTarget>,
    feedback_invalid: bool,
    feedback_invalid_this_tick: bool,
}

impl ArmEventReporter {
    /// The reporter of `arm`.
    pub fn new(arm: ArmId) -> Self {
        let number = arm.number();
        Self {
            number,
            source: match arm {
                ArmId::Arm1 => HarvestEventSource::Arm1,
                ArmId::Arm2 => HarvestEventSource::Arm2,
            },
            current: None,
            feedback_invalid: false,
            feedback_invalid_this_tick: false,
        }
    }

    /// Marks the end of a tick's events.
    pub fn end_tick(&mut self) {
        self.feedback_invalid = std::mem::take(&mut self.feedback_invalid_this_tick);
    }

    /// The target of the running attempt (taken by the arm, not ended yet).
    pub fn current_target(&self) -> Option<&ArmTarget> {
        self.current.as_ref()
    }

    /// The harvest event of `event`, if it is one worth publishing. `phase` is the arm's phase
    /// after the tick; `latest_target` the newest sample of this arm's target channel.
    pub fn convert(
        &mut self,
        now_ns: u64,
        phase: PhaseCode,
        event: &ArmNodeEvent,
        latest_target: Option<&ArmTarget>,
    ) -> Option<HarvestEvent> {
        let target_of = |apple_id: u32| latest_target.filter(|t| t.apple_id == apple_id).copied();
        let current_id = self.current.map_or(0, |t| t.apple_id);
        let (kind, apple_id, target, cause, flag, reason): (_, _, _, _, bool, Reason) = match event
        {
            ArmNodeEvent::TargetReceived { .. } | ArmNodeEvent::ValveRequested { .. } => {
                return None;
            }
            ArmNodeEvent::TargetAccepted { apple_id } => {
                self.current = target_of(*apple_id);
                (
                    HarvestEventKind::TargetAccepted,
                    *apple_id,
                    self.current,
                    HarvestCause::None,
                    false,
                    Reason::default(),
                )
            }
            ArmNodeEvent::TargetRejected {
                apple_id,
                reason,
                will_retry,
            } => (
                HarvestEventKind::TargetRejected,
                *apple_id,
                target_of(*apple_id),
                rejection_cause(reason),
                *will_retry,
                Reason::format(format_args!("{reason}")),
            ),
            ArmNodeEvent::TargetDeferred { apple_id, .. } => (
                HarvestEventKind::TargetDeferred,
                *apple_id,
                target_of(*apple_id),
                HarvestCause::None,
                false,
                Reason::new("other arm's state unknown or old"),
            ),
            ArmNodeEvent::PhaseChanged { from, to } => (
                HarvestEventKind::PhaseChanged,
                current_id,
                self.current,
                HarvestCause::None,
                false,
                Reason::format(format_args!("{from:?} -> {to:?}")),
            ),
            ArmNodeEvent::Cycle(CycleEvent::Attached) => (
                HarvestEventKind::Attached,
                current_id,
                self.current,
                HarvestCause::None,
                false,
                Reason::default(),
            ),
            ArmNodeEvent::Cycle(CycleEvent::FeedbackInvalid { .. })
                if std::mem::replace(&mut self.feedback_invalid_this_tick, true)
                    || self.feedback_invalid =>
            {
                return None;
            }
            ArmNodeEvent::Cycle(step) => {
                let cause = match step {
                    CycleEvent::ApproachTimeout => HarvestCause::ApproachTimeout,
                    CycleEvent::ValveGrantTimeout => HarvestCause::ValveNotGranted,
                    CycleEvent::AttachFailed => HarvestCause::NoAttachment,
                    CycleEvent::AppleLost => HarvestCause::AppleLost,
                    CycleEvent::ValveCloseTimeout => HarvestCause::ValveNotClosed,
                    CycleEvent::FeedbackInvalid { .. } => HarvestCause::NoFeedback,
                    _ => HarvestCause::None,
                };
                (
                    HarvestEventKind::CycleStep,
                    current_id,
                    self.current,
                    cause,
                    false,
                    Reason::format(format_args!("{step:?}")),
                )
            }
            ArmNodeEvent::ValveRefused { reason_code } => (
                HarvestEventKind::ValveRefused,
                current_id,
                self.current,
                HarvestCause::None,
                false,
                Reason::format(format_args!(
                    "open request refused by the vacuum supervisor (code {reason_code})"
                )),
            ),
            ArmNodeEvent::AttemptEnded {
                apple_id,
                harvested,
                failure,
            } => {
                let target = self.current.filter(|t| t.apple_id == *apple_id);
                self.current = None;
                (
                    HarvestEventKind::AttemptEnded,
                    *apple_id,
                    target,
                    failure.map_or(HarvestCause::None, failure_cause),
                    *harvested,
                    failure.map_or_else(Reason::default, |f| Reason::format(format_args!("{f:?}"))),
                )
            }
            ArmNodeEvent::EmergencyStop { engaged } => (
                HarvestEventKind::EmergencyStop,
                current_id,
                self.current,
                HarvestCause::None,
                *engaged,
                Reason::new(if *engaged { "engaged" } else { "released" }),
            ),
        };
        let mut out = HarvestEvent::new(now_ns, self.source, kind, self.number, apple_id);
        out.phase.set(phase);
        out.harvested = u8::from(flag);
        out.cause.set(cause);
        if let Some(t) = target {
            out.position_in_robot_m = t.position_in_robot_m;
        }
        out.reason = reason;
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_robot_model::kinematics::IkError;

    fn target(apple_id: u32) -> ArmTarget {
        ArmTarget {
            arm_id: 1,
            apple_id,
            position_in_robot_m: [1.2, 0.1, 0.3],
            radius_m: 0.04,
            ..ArmTarget::default()
        }
    }

    #[test]
    fn an_attempt_names_its_apple_from_acceptance_to_end() {
        let mut r = ArmEventReporter::new(ArmId::Arm1);
        let t = target(5);
        let accepted = r
            .convert(
                10,
                PhaseCode::Approach,
                &ArmNodeEvent::TargetAccepted { apple_id: 5 },
                Some(&t),
            )
            .expect("event");
        assert_eq!(accepted.kind, HarvestEventKind::TargetAccepted);
        assert_eq!(accepted.apple_id, 5);
        assert_eq!(accepted.position_in_robot_m, t.position_in_robot_m);
        assert_eq!(r.current_target().map(|t| t.apple_id), Some(5));
        let phase = r
            .convert(
                20,
                PhaseCode::Retract,
                &ArmNodeEvent::PhaseChanged {
                    from: PhaseCode::AttachDetach,
                    to: PhaseCode::Retract,
                },
                None,
            )
            .expect("event");
        assert_eq!(phase.apple_id, 5);
        assert_eq!(phase.phase, PhaseCode::Retract);
        let ended = r
            .convert(
                30,
                PhaseCode::Idle,
                &ArmNodeEvent::AttemptEnded {
                    apple_id: 5,
                    harvested: false,
                    failure: Some(AttemptFailure::NoAttachment),
                },
                None,
            )
            .expect("event");
        assert_eq!(ended.cause, HarvestCause::NoAttachment);
        assert_eq!(ended.harvested, 0);
        assert_eq!(ended.header.capture_ns, 30);
        assert!(r.current_target().is_none());
    }

    #[test]
    fn a_refused_target_carries_cause_and_reason() {
        let mut r = ArmEventReporter::new(ArmId::Arm2);
        let t = target(9);
        let event = r
            .convert(
                1,
                PhaseCode::Idle,
                &ArmNodeEvent::TargetRejected {
                    apple_id: 9,
                    reason: TargetRejection::Unreachable {
                        id: 9,
                        reason: IkError::NonFinite {
                            target_m: [f64::NAN; 3],
                        },
                    },
                    will_retry: false,
                },
                Some(&t),
            )
            .expect("event");
        assert_eq!(event.cause, HarvestCause::OutsideWorkspace);
        assert_eq!(event.source, HarvestEventSource::Arm2);
        assert_eq!(event.arm_id, 2);
        assert!(event.reason.as_str().contains("unreachable"), "{event:?}");
        assert!(
            r.convert(
                1,
                PhaseCode::Idle,
                &ArmNodeEvent::TargetReceived { apple_id: 9 },
                Some(&t)
            )
            .is_none()
        );
    }

    #[test]
    fn invalid_feedback_is_reported_when_it_starts() {
        let mut r = ArmEventReporter::new(ArmId::Arm1);
        let invalid = ArmNodeEvent::Cycle(CycleEvent::FeedbackInvalid { age_s: 1.0 });
        let mut published = Vec::new();
        for tick in 0..6 {
            // Invalid on ticks 0-2 and 4, valid on 3 and 5.
            if tick != 3 && tick != 5 {
                published.push(r.convert(tick, PhaseCode::Idle, &invalid, None).is_some());
            }
            r.end_tick();
        }
        assert_eq!(published, [true, false, false, true]);
    }
}
