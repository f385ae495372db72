//! [`CycleEvent`]: what happened during one step of the picking cycle.

use serde::{Deserialize, Serialize};

/// Something that happened during a step (at most one per step).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum CycleEvent {
    /// Reached the apple; valve requested open.
    ApproachComplete,
    /// Did not settle at the apple in time; retracting without attaching.
    ApproachTimeout,
    /// The valve was not granted in time; retracting.
    ValveGrantTimeout,
    /// Pressure feedback confirmed the attachment; twisting.
    Attached,
    /// No attachment within the timeout; valve closed, retracting (Fig. 9, failure branch).
    AttachFailed,
    /// The apple came off after attaching; valve closed immediately (eq. 11).
    AppleLost,
    /// The twist finished; retracting with the apple.
    DetachComplete,
    /// Back at the drop-off with an apple; valve requested closed.
    RetractComplete,
    /// The valve did not report closed in time at the drop-off.
    ValveCloseTimeout,
    /// The cycle ended; `harvested` tells whether an apple was released.
    CycleComplete {
        /// True when an apple reached the drop-off and was released.
        harvested: bool,
    },
    /// Joint feedback was non-finite or older than allowed; the arm was stopped.
    FeedbackInvalid {
        /// Feedback age, s.
        age_s: f64,
    },
    /// The step came more than `max_tick_gap_periods` after the previous one (the control loop
    /// missed its deadline); the arm was stopped as after a feedback outage and its motion
    /// restarts from where it is on the next step.
    DeadlineMissed {
        /// Time since the previous step, s.
        gap_s: f64,
    },
}
