//! What the node tracks per arm: [`ArmTrack`], with the target [`Dispatch`]ed to it and the
//! apple [`Withdrawal`] taken back from it.

use crate::assignment::{Apple, AppleId};
use harvest_ipc::payloads::ArmTarget;

/// A target handed to an arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Dispatch {
    pub(super) apple: Apple,
    pub(super) at_ns: u64,
    pub(super) harvested_before: u32,
}

/// An apple taken back from an arm that kept waiting for the other arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Withdrawal {
    pub(super) apple: AppleId,
    pub(super) position_m: [f64; 3],
    pub(super) at_ns: u64,
    /// Handed to the other arm (which can reach it): while the back-off lasts, the assignment
    /// treats it as out of this arm's reach, so re-planning does not hand it straight back.
    pub(super) to_other: bool,
}

/// What the node tracks per arm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct ArmTrack {
    /// Commanded: source valve open (valve 1 or 3 open, 2 or 4 closed).
    pub(super) valve_open: bool,
    /// When the valve was last opened, ns.
    pub(super) opened_at_ns: u64,
    /// Dispatched, not yet taken up.
    pub(super) dispatched: Option<Dispatch>,
    /// Taken up, running.
    pub(super) active: Option<Dispatch>,
    /// The valve was granted during the current attempt.
    pub(super) opened_in_cycle: bool,
    /// Request sequence of the last open granted (never granted twice).
    pub(super) granted_seq: Option<u32>,
    /// Last refusal reported: (request seq, code).
    pub(super) refused: Option<(u32, u8)>,
    /// Standing open request first seen at, ns (oldest waiter served first).
    pub(super) open_request_since_ns: Option<(u32, u64)>,
    /// Last approach refusal reported.
    pub(super) approach_refusal: Option<u8>,
    /// Last dispatch time, ns (dispatch fairness).
    pub(super) last_dispatch_ns: u64,
    /// The last target published for this arm.
    pub(super) last_target: Option<ArmTarget>,
    /// The apple last withdrawn from this arm (adopted if the arm took it up regardless; not
    /// dispatched to it again within `withdrawal_backoff_s`).
    pub(super) withdrawn: Option<Withdrawal>,
    /// Highest arm vacuum read while the cup was sealed during the running attempt, mmH2O.
    pub(super) sealed_peak_mmh2o: f32,
    /// The seal was lost with the valve open during the running attempt, after the cup held
    /// this peak vacuum, mmH2O.
    pub(super) seal_lost_after_mmh2o: Option<f32>,
}
