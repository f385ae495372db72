//! The vacuum supervisor's node events as `harvest/events` messages ([`HarvestEvent`]): the
//! assignments, valve decisions, attachment changes and attempt results that `harvest up`
//! prints and summarizes ([`harvest_log`]).

use harvest_ipc::payloads::{
    ArmPhase, HarvestCause, HarvestEvent, HarvestEventKind, HarvestEventSource,
};
use harvest_ipc::{FixedString, WireCode};

use crate::node::{VacuumNodeEvent, ValveCloseCause, wire_id};
use crate::replan::AttemptResult;
use harvest_robot_model::ArmId;

/// What the vacuum process knows of each arm when it converts an event: its last published
/// phase code and apple (from `armN/state`), indexed by [`ArmId::index`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ArmContext {
    /// `ArmState::phase` codes, as published.
    pub phase: [WireCode<ArmPhase>; 2],
    /// `ArmState::apple_id` (0 none).
    pub apple_id: [u32; 2],
}

/// The harvest event of `event`, if it is one worth publishing. Re-plans that changed nothing
/// and target refreshes are left out (they come with every detection set).
pub fn vacuum_event(
    now_ns: u64,
    event: &VacuumNodeEvent,
    arms: &ArmContext,
) -> Option<HarvestEvent> {
    let make = |kind: HarvestEventKind, arm: Option<ArmId>, apple_id: Option<u32>| {
        let (number, phase, apple) = match arm {
            Some(arm) => (
                arm.number(),
                arms.phase[arm.index()],
                apple_id.unwrap_or(arms.apple_id[arm.index()]),
            ),
            None => (0, ArmPhase::Idle.into(), apple_id.unwrap_or(0)),
        };
        let mut out = HarvestEvent::new(now_ns, HarvestEventSource::Vacuum, kind, number, apple);
        out.phase = phase;
        out
    };
    let event = match event {
        VacuumNodeEvent::Replanned {
            summary,
            queued,
            invalid,
            given_up,
        } => {
            if summary.added
                + summary.dropped
                + summary.exhausted
                + summary.held
                + invalid
                + given_up
                == 0
            {
                return None;
            }
            let mut out = make(HarvestEventKind::Replanned, None, None);
            out.reason = FixedString::format(format_args!(
                "queued {}/{}; added {}, dropped {}, exhausted {}, held {}, invalid {}, given up {}",
                queued[0],
                queued[1],
                summary.added,
                summary.dropped,
                summary.exhausted,
                summary.held,
                invalid,
                given_up
            ));
            out
        }
        VacuumNodeEvent::ReplanFailed { message } => {
            let mut out = make(HarvestEventKind::Replanned, None, None);
            out.cause.set(HarvestCause::Other);
            out.reason = FixedString::new(message);
            out
        }
        VacuumNodeEvent::TargetDispatched { arm, target } => {
            let mut out = make(
                HarvestEventKind::Assigned,
                Some(*arm),
                Some(target.apple_id),
            );
            out.position_in_robot_m = target.position_in_robot_m;
            out
        }
        VacuumNodeEvent::DispatchTimedOut { arm, apple } => {
            let mut out = make(
                HarvestEventKind::DispatchTimedOut,
                Some(*arm),
                Some(wire_id(*apple)),
            );
            out.cause.set(HarvestCause::TargetNotTaken);
            out.reason = FixedString::new("the arm did not take the target up");
            out
        }
        VacuumNodeEvent::TargetRefused { arm, apple } => {
            let mut out = make(
                HarvestEventKind::DispatchTimedOut,
                Some(*arm),
                Some(wire_id(*apple)),
            );
            out.cause.set(HarvestCause::TargetNotTaken);
            out.reason = FixedString::new("the arm refused the target");
            out
        }
        VacuumNodeEvent::TargetWithdrawn { arm, apple, to } => {
            let mut out = make(
                HarvestEventKind::TargetDeferred,
                Some(*arm),
                Some(wire_id(*apple)),
            );
            out.reason = FixedString::format(format_args!(
                "withdrawn while the arm waited for the other arm; queued for arm {}",
                to.number()
            ));
            out
        }
        VacuumNodeEvent::AttemptFinished { arm, apple, result } => {
            let mut out = make(
                HarvestEventKind::AttemptFinished,
                Some(*arm),
                Some(wire_id(*apple)),
            );
            out.harvested = u8::from(*result == AttemptResult::Harvested);
            out
        }
        VacuumNodeEvent::ValveOpened { arm } => {
            make(HarvestEventKind::ValveOpened, Some(*arm), None)
        }
        VacuumNodeEvent::ValveRefused { arm, reason } => {
            let mut out = make(HarvestEventKind::ValveRefused, Some(*arm), None);
            out.reason = match reason {
                Some(reason) => FixedString::format(format_args!("{reason}")),
                None => FixedString::new("emergency stop or arm disabled"),
            };
            out
        }
        VacuumNodeEvent::ValveClosed { arm, cause } => {
            let mut out = make(HarvestEventKind::ValveClosed, Some(*arm), None);
            out.reason = match cause {
                ValveCloseCause::ArmRequest => FixedString::new("on the arm's request"),
                ValveCloseCause::Policy(reason) => {
                    FixedString::format(format_args!("policy: {reason}"))
                }
                ValveCloseCause::EmergencyStop => FixedString::new("emergency stop"),
                ValveCloseCause::Interlock => {
                    FixedString::new("interlock: both valves open, neither cup sealed")
                }
            };
            out
        }
        VacuumNodeEvent::Attachment(change) => {
            let mut out = make(HarvestEventKind::AttachmentChanged, Some(change.arm), None);
            out.reason = FixedString::format(format_args!("{} -> {}", change.from, change.to));
            out
        }
        VacuumNodeEvent::EmergencyStop { engaged } => {
            let mut out = make(HarvestEventKind::EmergencyStop, None, None);
            out.harvested = u8::from(*engaged);
            out.reason = FixedString::new(if *engaged { "engaged" } else { "released" });
            out
        }
        VacuumNodeEvent::TargetRefreshed { .. }
        | VacuumNodeEvent::ApproachRefused { .. }
        | VacuumNodeEvent::AttemptStarted { .. }
        | VacuumNodeEvent::SampleRefused(_) => return None,
    };
    Some(event)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assignment::AppleId;
    use harvest_ipc::payloads::ArmTarget;

    #[test]
    fn a_dispatch_becomes_an_assignment_with_position() {
        let target = ArmTarget {
            arm_id: 2,
            apple_id: 4,
            position_in_robot_m: [1.1, -0.2, 0.4],
            ..ArmTarget::default()
        };
        let event = vacuum_event(
            7,
            &VacuumNodeEvent::TargetDispatched {
                arm: ArmId::Arm2,
                target,
            },
            &ArmContext::default(),
        )
        .expect("event");
        assert_eq!(event.kind, HarvestEventKind::Assigned);
        assert_eq!(event.arm_id, 2);
        assert_eq!(event.apple_id, 4);
        assert_eq!(event.position_in_robot_m, target.position_in_robot_m);
        assert_eq!(event.source, HarvestEventSource::Vacuum);
    }

    #[test]
    fn valve_events_name_the_arms_apple_and_timeouts_their_cause() {
        let arms = ArmContext {
            phase: [ArmPhase::AttachDetach.into(), ArmPhase::Idle.into()],
            apple_id: [9, 0],
        };
        let opened = vacuum_event(1, &VacuumNodeEvent::ValveOpened { arm: ArmId::Arm1 }, &arms)
            .expect("event");
        assert_eq!(opened.apple_id, 9);
        assert_eq!(opened.phase, ArmPhase::AttachDetach);
        let timed_out = vacuum_event(
            2,
            &VacuumNodeEvent::DispatchTimedOut {
                arm: ArmId::Arm2,
                apple: AppleId(3),
            },
            &arms,
        )
        .expect("event");
        assert_eq!(timed_out.apple_id, wire_id(AppleId(3)));
        assert_eq!(timed_out.cause, HarvestCause::TargetNotTaken);
    }
}
