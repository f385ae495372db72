//! harvest-field: the field workflow's pure logic ([dual-arm sec. 2.2 and 4.1]: stop and
//! go along a row; at each stop the platform movement mechanism moves the robot so that the
//! arms' workspace overlaps the fruiting area as much as possible).
//!
//! - [`positioning`]: the in-out / up-down offsets that put the most detected apples in reach
//!   of either arm, from the arms' kinematic models, the stages' travel and the other arm.
//! - [`stop_cycle`]: the stop-and-go sequencer (arrive, park, position, settle, harvest,
//!   advance), transport-free; the executive drives it.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod positioning;
pub mod stop_cycle;

pub use positioning::{
    Positioning, PositioningError, StageTravel, choose_offsets, reachable_count,
};
pub use stop_cycle::{
    FieldAction, FieldView, NextStopRefusal, RowReport, StopCycle, StopCycleConfig, StopCycleError,
    StopPhase, StopReport,
};
