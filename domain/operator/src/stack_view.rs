//! What the executive knows of the stack when it decides: each arm's latest state and the
//! platform's position.

use harvest_ipc::payloads::{ArmPhase, ArmState};

/// One arm as its latest `armN/state` shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmView {
    /// `[D m, theta rad, phi rad, twist rad]`.
    pub joint_position: [f64; 4],
    /// `[m/s, rad/s, rad/s, rad/s]`.
    pub joint_velocity: [f64; 4],
    /// Its picking-cycle phase (`None`: unknown code).
    pub phase: Option<ArmPhase>,
    /// Since the state's capture, ns.
    pub age_ns: u64,
}

impl ArmView {
    /// The view of `state` at `now_ns`.
    pub fn from_state(state: &ArmState, now_ns: u64) -> Self {
        Self {
            joint_position: state.joint_position,
            joint_velocity: state.joint_velocity,
            phase: state.phase.get().ok(),
            age_ns: now_ns.saturating_sub(state.header.capture_ns),
        }
    }
}

/// The platform as its driver reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformView {
    /// `[in_out, up_down]`, m.
    pub position_m: [f64; 2],
    /// True while a stage moves.
    pub in_motion: bool,
    /// Stroke of each stage `[in_out, up_down]`, m (travel `[0, max]`).
    pub travel_max_m: [f64; 2],
}

/// Everything the executive looks at besides the command.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StackView {
    /// Arm 1 and arm 2 (`None`: no state received yet).
    pub arms: [Option<ArmView>; 2],
    /// The platform (`None`: the executive drives none).
    pub platform: Option<PlatformView>,
}
