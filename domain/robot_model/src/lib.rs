//! harvest-robot-model: what the arm, the vacuum supervisor, the safety monitor and the
//! simulator share about the robot ([dual-arm sec. 2.2]): which arm, the picking phases the
//! coordination reasons about, the failure kinds, the Table 1 parameters with the joint limits,
//! eq. 1-2 kinematics (forward, inverse, Jacobian), the swept-tube clearance between the arms,
//! and the one rule by which every node obeys the operator's mode ([`obedience`](mod@obedience)).
//!
//! Pure: no transport, no clock, no simulator.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod clearance;
pub mod coordination_phase;
pub mod failure_kind;
pub mod joint;
pub mod kinematics;
pub mod obedience;
pub mod params;

pub use coordination_phase::CoordinationPhase;
pub use failure_kind::FailureKind;
/// The one arm identifier of the stack (defined in `harvest-ipc`, which selects channels by it).
pub use harvest_ipc::ArmId;
pub use obedience::{ModeSource, Obedience, obedience};
