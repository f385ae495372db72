//! What happened to each apple: the harvest's event trace (`harvest/events`), published by the
//! arm processes and the vacuum supervisor, read by `harvest up` (per-apple lines and the
//! harvest summary), the recorder and offline checkers.

use crate::fixed_string::FixedString;
use crate::header::Header;
use crate::payloads::ArmPhase;
use crate::wire_code::WireCode;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Capacity of [`HarvestEvent::reason`], bytes.
pub const HARVEST_EVENT_REASON_BYTES: usize = 96;

/// Which process reported the event (code in [`HarvestEvent::source`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum HarvestEventSource {
    /// Arm 1's process.
    Arm1 = 1,
    /// Arm 2's process.
    Arm2 = 2,
    /// The vacuum supervisor.
    Vacuum = 3,
    /// The executive's stop-and-go cycle along a row.
    Field = 4,
}

impl HarvestEventSource {
    /// The source of arm `number` (1 or 2).
    pub fn arm(number: u8) -> Option<Self> {
        match number {
            1 => Some(Self::Arm1),
            2 => Some(Self::Arm2),
            _ => None,
        }
    }

    /// `arm1`, `arm2` or `vacuum`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Arm1 => "arm1",
            Self::Arm2 => "arm2",
            Self::Vacuum => "vacuum",
            Self::Field => "field",
        }
    }
}

/// What happened (code in [`HarvestEvent::kind`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum HarvestEventKind {
    /// Vacuum: the apple was assigned and its target published to `arm_id`.
    Assigned = 1,
    /// Arm: the target was taken; the approach starts.
    TargetAccepted = 2,
    /// Arm: the target was refused (`cause` says why, `reason` in words); `harvested` is 1 when
    /// the refusal depends on the moment and the target is retried.
    TargetRejected = 3,
    /// Arm: the target is held back until the other arm's state is known.
    TargetDeferred = 4,
    /// Arm: the published phase changed to `phase`.
    PhaseChanged = 5,
    /// Arm: the pressure showed a seal; twisting the apple off.
    Attached = 6,
    /// Arm: a picking-cycle step (`reason` names it: approach complete, detach complete, ...).
    CycleStep = 7,
    /// Arm: the attempt ended; `harvested` and `cause` tell how.
    AttemptEnded = 8,
    /// Vacuum: the arm's valve was opened on its request.
    ValveOpened = 9,
    /// Vacuum: the arm's valve was closed (`reason` says why).
    ValveClosed = 10,
    /// Vacuum (or arm, for the answer it got): an open request was refused (`reason`).
    ValveRefused = 11,
    /// Either: the emergency stop was engaged (`harvested` 1) or released (0).
    EmergencyStop = 12,
    /// Vacuum: the arm's attempt is over as the supervisor sees it (`harvested`).
    AttemptFinished = 13,
    /// Vacuum: the dispatched target was never taken up; counted as a failed attempt.
    DispatchTimedOut = 14,
    /// Vacuum: a detection set re-planned the assignment (`reason`: queue lengths).
    Replanned = 15,
    /// Vacuum: the attachment inferred from pressure changed (`reason`: to what).
    AttachmentChanged = 16,
    /// Vacuum: nothing is assigned, dispatched or running, both arms are idle and the newest
    /// detection sets hold nothing to pick: the harvest of what the camera sees is complete.
    HarvestComplete = 17,
    /// Field: a stop of the row is done; `reason` holds its figures (positioning, reachable
    /// before/after, out of reach, attempted, harvested), `position_in_robot_m[0]` the
    /// trailer position along the row, m.
    StopFinished = 18,
    /// Field: the last stop of the row is done.
    RowFinished = 19,
}

/// Why an attempt failed or a target was refused (code in [`HarvestEvent::cause`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, crate::WireEnum)]
pub enum HarvestCause {
    /// No failure (or not applicable).
    None = 0,
    // Attempt failures (the arm's account).
    /// The arm did not settle at the apple in time.
    ApproachTimeout = 1,
    /// The vacuum supervisor did not open the valve in time.
    ValveNotGranted = 2,
    /// No seal within the attach timeout.
    NoAttachment = 3,
    /// The seal was lost after attaching (apple slipped, dropped or knocked off).
    AppleLost = 4,
    /// At the drop-off the valve never reported closed.
    ValveNotClosed = 5,
    /// The emergency stop abandoned the attempt.
    EmergencyStop = 6,
    /// The arm never took the target up (the vacuum supervisor gave it up).
    TargetNotTaken = 7,
    // Target refusals.
    /// A coordinate is NaN or infinite.
    NonFinite = 20,
    /// The detection behind the target is too old.
    Stale = 21,
    /// The detection is stamped in the future.
    FromFuture = 22,
    /// Outside the arm's workspace (no inverse kinematics within the joint limits).
    OutsideWorkspace = 23,
    /// The arm is busy with another apple.
    Busy = 24,
    /// The motion would come too close to the other arm (retried).
    ClearanceConflict = 25,
    /// The other arm approaches an unknown goal (retried).
    OtherArmGoalUnknown = 26,
    /// No valid joint feedback.
    NoFeedback = 27,
    /// Anything else (`reason` says what).
    Other = 255,
}

impl HarvestCause {
    /// A short snake_case label (`no_attachment`, `outside_workspace`, ...).
    pub fn label(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::ApproachTimeout => "approach_timeout",
            Self::ValveNotGranted => "valve_not_granted",
            Self::NoAttachment => "no_attachment",
            Self::AppleLost => "apple_lost",
            Self::ValveNotClosed => "valve_not_closed",
            Self::EmergencyStop => "emergency_stop",
            Self::TargetNotTaken => "target_not_taken",
            Self::NonFinite => "non_finite",
            Self::Stale => "stale",
            Self::FromFuture => "from_future",
            Self::OutsideWorkspace => "outside_workspace",
            Self::Busy => "busy",
            Self::ClearanceConflict => "clearance_conflict",
            Self::OtherArmGoalUnknown => "other_arm_goal_unknown",
            Self::NoFeedback => "no_feedback",
            Self::Other => "other",
        }
    }
}

/// One event of the harvest.
#[repr(C)]
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    ZeroCopySend,
    Serialize,
    Deserialize,
    crate::AnyBitPattern,
    crate::Payload,
)]
#[type_name("harvest.HarvestEvent.v1")]
pub struct HarvestEvent {
    /// `capture_ns`: the control tick the event happened at.
    pub header: Header,
    /// Which process reported the event.
    pub source: WireCode<HarvestEventSource>,
    /// What happened.
    pub kind: WireCode<HarvestEventKind>,
    /// The arm concerned (1 or 2; 0 none).
    pub arm_id: u8,
    /// The arm's phase after the event (for the vacuum's events: the arm's last published
    /// phase).
    pub phase: WireCode<ArmPhase>,
    /// 1 when the attempt harvested its apple (`AttemptEnded`, `AttemptFinished`), when the
    /// refusal is retried (`TargetRejected`), when engaged (`EmergencyStop`).
    pub harvested: u8,
    /// Why, for failures and refusals ([`HarvestCause::None`] otherwise).
    pub cause: WireCode<HarvestCause>,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 2],
    /// The apple (the vacuum supervisor's id as on `armN/target`; 0 none).
    pub apple_id: u32,
    /// Zero; keeps the following fields aligned.
    pub _reserved2: u32,
    /// The apple centre, robot frame, m (NaN when unknown).
    pub position_in_robot_m: [f64; 3],
    /// A short human-readable reason or detail.
    pub reason: FixedString<HARVEST_EVENT_REASON_BYTES>,
}

impl HarvestEvent {
    /// An event with the given source, kind, arm and apple; everything else zero, the position
    /// NaN and no reason.
    pub fn new(
        stamp_ns: u64,
        source: HarvestEventSource,
        kind: HarvestEventKind,
        arm_id: u8,
        apple_id: u32,
    ) -> Self {
        Self {
            header: Header {
                msg_seq: 0,
                capture_ns: stamp_ns,
                publish_ns: 0,
            },
            source: source.into(),
            kind: kind.into(),
            arm_id,
            apple_id,
            position_in_robot_m: [f64::NAN; 3],
            ..Self::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::payload::Payload;
    use crate::wire_code::WireEnum;

    #[test]
    fn codes_match_the_schema() {
        assert_eq!(
            HarvestEventKind::from_code(17),
            Some(HarvestEventKind::HarvestComplete)
        );
        assert_eq!(HarvestEventKind::ALL.len(), 19);
        assert_eq!(
            HarvestCause::from_code(23),
            Some(HarvestCause::OutsideWorkspace)
        );
        assert_eq!(HarvestCause::Other.code(), 255);
        assert_eq!(HarvestEventSource::arm(2), Some(HarvestEventSource::Arm2));
    }

    #[test]
    fn encodes_and_decodes() {
        let mut event = HarvestEvent::new(
            42,
            HarvestEventSource::Arm1,
            HarvestEventKind::TargetRejected,
            1,
            7,
        );
        event.cause.set(HarvestCause::OutsideWorkspace);
        event.position_in_robot_m = [3.0, 0.0, 0.5];
        event.reason = FixedString::new("target 7 is unreachable");
        let mut bytes = Vec::new();
        event.encode(&mut bytes).expect("encode");
        let mut back = HarvestEvent::default();
        HarvestEvent::decode_into(&bytes, &mut back).expect("decode");
        assert_eq!(back, event);
        assert_eq!(back.reason.as_str(), "target 7 is unreachable");
        assert_eq!(back.kind, HarvestEventKind::TargetRejected);
    }
}
