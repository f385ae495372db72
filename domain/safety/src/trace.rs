//! Plain, time-stamped facts about a harvesting episode, as the safety monitor consumes them.
//!
//! Producers: the cycle model (`harvest_eval::cycle_model`), and later the full simulator and the
//! recorder replaying a field log. Consumer: [`crate::safety_monitor`]. The events carry only
//! observations (valve commands, what the pressure inference concluded, joint commands,
//! end-effector positions), never a policy's reasoning, so the monitor can judge a trace without
//! sharing code with the policies.

use harvest_robot_model::ArmId;
pub use harvest_robot_model::FailureKind;
use harvest_robot_model::coordination_phase::CoordinationPhase;
use serde::{Deserialize, Serialize};

/// Joints of one 4-DOF tube arm ([dual-arm sec. 2.2, eq. 1]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum JointId {
    /// Prismatic extension `D`, metres.
    Extension,
    /// Pitch `theta`, radians.
    Pitch,
    /// Yaw `phi`, radians.
    Yaw,
    /// End-effector twist used for the detach rotation, radians.
    Twist,
}

/// One time-stamped observation. `stamp_ns` is the time of validity on the episode's clock.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum TraceEvent {
    /// The arm's source valve was commanded open (tube connected to the vacuum source).
    ValveOpened {
        /// Time of the command, ns.
        stamp_ns: u64,
        /// Whose valve.
        arm: ArmId,
    },
    /// The arm's source valve was commanded closed (tube vented to the atmosphere).
    ValveClosed {
        /// Time of the command, ns.
        stamp_ns: u64,
        /// Whose valve.
        arm: ArmId,
    },
    /// The inferred seal state of an arm changed.
    AttachmentChanged {
        /// Time the inference changed, ns.
        stamp_ns: u64,
        /// Which arm.
        arm: ArmId,
        /// True when an apple seals the arm's end-effector.
        sealed: bool,
    },
    /// The pressure inference detected a failed attachment or a drop.
    FailureDetected {
        /// Time of detection, ns.
        stamp_ns: u64,
        /// Which arm.
        arm: ArmId,
        /// What failed.
        kind: FailureKind,
    },
    /// The arm's workflow phase changed (informative; the monitor does not need it).
    PhaseChanged {
        /// Time of the change, ns.
        stamp_ns: u64,
        /// Which arm.
        arm: ArmId,
        /// The new phase.
        phase: CoordinationPhase,
    },
    /// A joint position command sent to a servo, with the limits it must respect.
    JointCommand {
        /// Time of the command, ns.
        stamp_ns: u64,
        /// Which arm.
        arm: ArmId,
        /// Which joint.
        joint: JointId,
        /// Commanded position (m for the extension, rad otherwise).
        command: f64,
        /// Lower limit, same unit as `command`.
        lower: f64,
        /// Upper limit, same unit as `command`.
        upper: f64,
    },
    /// The emergency stop was engaged or released (`safety/emergency_stop`).
    EmergencyStop {
        /// Time of the change, ns.
        stamp_ns: u64,
        /// True while engaged.
        engaged: bool,
    },
    /// Positions of both end-effectors in one common frame (the robot frame), metres.
    EndEffectors {
        /// Time of validity, ns.
        stamp_ns: u64,
        /// Arm 1's end-effector, m.
        arm1_in_robot_m: [f64; 3],
        /// Arm 2's end-effector, m.
        arm2_in_robot_m: [f64; 3],
    },
}

impl TraceEvent {
    /// The event's time of validity, ns.
    pub const fn stamp_ns(&self) -> u64 {
        match *self {
            TraceEvent::ValveOpened { stamp_ns, .. }
            | TraceEvent::ValveClosed { stamp_ns, .. }
            | TraceEvent::AttachmentChanged { stamp_ns, .. }
            | TraceEvent::FailureDetected { stamp_ns, .. }
            | TraceEvent::PhaseChanged { stamp_ns, .. }
            | TraceEvent::JointCommand { stamp_ns, .. }
            | TraceEvent::EmergencyStop { stamp_ns, .. }
            | TraceEvent::EndEffectors { stamp_ns, .. } => stamp_ns,
        }
    }
}
