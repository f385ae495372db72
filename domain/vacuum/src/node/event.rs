//! [`VacuumNodeEvent`]: what the vacuum node did or saw during a tick.

use crate::assignment::AppleId;
use crate::policy::{CloseReason, RefuseReason};
use crate::pressure::{AttachmentChange, PressureSampleError};
use crate::replan::{AttemptResult, ReplanSummary};
use harvest_ipc::payloads::ArmTarget;
use harvest_robot_model::ArmId;

/// Why a valve was closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValveCloseCause {
    /// The arm asked (release at the drop-off, or it gave up the attempt).
    ArmRequest,
    /// The policy ordered it.
    Policy(CloseReason),
    /// Emergency stop.
    EmergencyStop,
    /// The interlock: both valves were open with neither cup sealed (module docs, step 6).
    Interlock,
}

/// Something the node did or saw this tick.
#[derive(Debug, Clone, PartialEq)]
pub enum VacuumNodeEvent {
    /// A detection set re-planned the assignment.
    Replanned {
        /// What changed.
        summary: ReplanSummary,
        /// Queue lengths after it, per arm.
        queued: [usize; 2],
        /// Detections dropped for a non-finite position.
        invalid: usize,
        /// Detections ignored because they lie on the give-up list.
        given_up: usize,
    },
    /// A dispatched target not taken up yet was published again with the capture time of a
    /// detection set that still sees the apple (so it does not go stale while its arm waits
    /// for the other arm's path to clear).
    TargetRefreshed {
        /// The arm.
        arm: ArmId,
        /// The target.
        target: ArmTarget,
    },
    /// The planner refused a detection set (nothing changed).
    ReplanFailed {
        /// The planner's message.
        message: String,
    },
    /// A target was published for an arm.
    TargetDispatched {
        /// The arm.
        arm: ArmId,
        /// The target.
        target: ArmTarget,
    },
    /// The policy kept an idle arm with apples at the drop-off (reported once per reason).
    ApproachRefused {
        /// The arm.
        arm: ArmId,
        /// Why.
        reason: RefuseReason,
    },
    /// The arm took up its target.
    AttemptStarted {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
    },
    /// The arm did not take up its target in time; counted as a failed attempt.
    DispatchTimedOut {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
    },
    /// The arm refused its target for good (outside its workspace, stale, not finite);
    /// counted as a failed attempt.
    TargetRefused {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
    },
    /// The arm kept refusing its target for the moment (the other arm in the way): the apple
    /// was taken back, not counted as an attempt, and queued for `to`.
    TargetWithdrawn {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
        /// The arm whose queue it joined (the other arm at its head, or the same arm at its
        /// back).
        to: ArmId,
    },
    /// An attempt ended (the arm is idle again).
    AttemptFinished {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
        /// Harvested or failed.
        result: AttemptResult,
    },
    /// An arm's valve was opened on its request.
    ValveOpened {
        /// The arm.
        arm: ArmId,
    },
    /// An arm's open request was refused (reported once per request and reason).
    ValveRefused {
        /// The arm.
        arm: ArmId,
        /// Why (`None`: emergency stop or disabled arm).
        reason: Option<RefuseReason>,
    },
    /// An arm's valve was closed.
    ValveClosed {
        /// The arm.
        arm: ArmId,
        /// Why.
        cause: ValveCloseCause,
    },
    /// The attachment inference of an arm changed.
    Attachment(AttachmentChange),
    /// A pressure sample was refused (state unchanged).
    SampleRefused(PressureSampleError),
    /// The emergency stop was engaged (true) or released (false).
    EmergencyStop {
        /// New state.
        engaged: bool,
    },
}
