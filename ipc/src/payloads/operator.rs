//! Operator channels: commands from the operator's tools (`harvest ctl`, the console, later the
//! safety monitor) to the executive, the executive's acknowledgement of each, and the stack's
//! operating mode as the executive enforces it (`domain/operator`, `processes/executive`).
//!
//! Codes travel as integers. A receiver turns them into the typed enums below with `from_code`,
//! which returns `None` for a code it does not know: a command with an unknown code is refused,
//! never acted on (so an older executive refuses commands added later, such as the field-row
//! cycle's "next stop" and "advance").

use crate::fixed_string::FixedString;
use crate::header::Header;
use iceoryx2::prelude::ZeroCopySend;
use serde::{Deserialize, Serialize};

/// Capacity of [`OperatorCommand::token`], bytes (the token is 32 hexadecimal digits).
pub const OPERATOR_TOKEN_BYTES: usize = 64;
/// Capacity of [`OperatorAck::reason`] and [`OperatorModeState::last_change_reason`], bytes.
pub const OPERATOR_REASON_BYTES: usize = 128;
/// Capacity of the client label of a session, bytes.
pub const OPERATOR_CLIENT_BYTES: usize = 32;

/// What the operator asks for (code in [`OperatorCommand::code`]).
#[repr(u16)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum OperatorCommandCode {
    /// Start harvesting (from idle, paused or manual).
    Start = 1,
    /// Pause: no new approach; arms finish the attempt they run.
    Pause = 2,
    /// Resume harvesting after a pause.
    Resume = 3,
    /// Stop harvesting (or manual motion) and go idle.
    Stop = 4,
    /// Engage the emergency stop (protective stop).
    EmergencyStop = 5,
    /// Release the emergency stop (the only way it is released).
    Release = 6,
    /// Send both arms to their home (drop-off) pose.
    Home = 7,
    /// Let arm `arm_id` take part in the harvest.
    ArmEnable = 8,
    /// Give arm `arm_id` no new apple (it finishes the one it picks).
    ArmDisable = 9,
    /// Move joint `joint` of arm `arm_id` by `value` (m or rad).
    Jog = 10,
    /// Send arm `arm_id` to its drop-off pose.
    DropOff = 11,
    /// Move the platform stages to `platform_target_m` (`[in_out, up_down]`, m).
    PlatformMove = 12,
    /// The controlling session is alive (sent every 100-200 ms by a controlling client).
    Heartbeat = 13,
    /// The session gives up control.
    LeaveControl = 14,
    /// End the harvest at the row's current stop and advance to the next one
    /// (`StopCycle::next_stop` in `domain/field`).
    NextStop = 15,
}

impl OperatorCommandCode {
    /// Every command code, in code order.
    pub const ALL: [Self; 15] = [
        Self::Start,
        Self::Pause,
        Self::Resume,
        Self::Stop,
        Self::EmergencyStop,
        Self::Release,
        Self::Home,
        Self::ArmEnable,
        Self::ArmDisable,
        Self::Jog,
        Self::DropOff,
        Self::PlatformMove,
        Self::Heartbeat,
        Self::LeaveControl,
        Self::NextStop,
    ];

    /// The command of `code`, `None` for a code this build does not know.
    pub fn from_code(code: u16) -> Option<Self> {
        Self::ALL.into_iter().find(|known| *known as u16 == code)
    }

    /// The command's name as `harvest ctl` and the console spell it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Start => "start",
            Self::Pause => "pause",
            Self::Resume => "resume",
            Self::Stop => "stop",
            Self::EmergencyStop => "estop",
            Self::Release => "release",
            Self::Home => "home",
            Self::ArmEnable => "arm-enable",
            Self::ArmDisable => "arm-disable",
            Self::Jog => "jog",
            Self::DropOff => "drop-off",
            Self::PlatformMove => "platform",
            Self::Heartbeat => "heartbeat",
            Self::LeaveControl => "leave-control",
            Self::NextStop => "next-stop",
        }
    }
}

/// The stack's operating mode (code in [`OperatorModeState::mode`]).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum OperatorModeCode {
    /// Up, not harvesting; nothing moves.
    Idle = 1,
    /// Apples are assigned and picked.
    Harvesting = 2,
    /// No new approach; arms finish the attempt they run, then stay idle.
    Paused = 3,
    /// Operator moves (jog, drop-off, home, platform); no harvesting.
    Manual = 4,
    /// The emergency stop is engaged: nothing moves until it is released.
    EmergencyStopped = 5,
}

impl OperatorModeCode {
    /// Every mode, in code order.
    pub const ALL: [Self; 5] = [
        Self::Idle,
        Self::Harvesting,
        Self::Paused,
        Self::Manual,
        Self::EmergencyStopped,
    ];

    /// The mode with this wire code; `None` for an unknown code.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|known| *known as u8 == code)
    }

    /// The mode's name as the console and `ctl` print it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Idle => "idle",
            Self::Harvesting => "harvesting",
            Self::Paused => "paused",
            Self::Manual => "manual",
            Self::EmergencyStopped => "estopped",
        }
    }
}

/// Why a command was refused (code in [`OperatorAck::refusal`]; 0 when accepted).
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum OperatorRefusalCode {
    /// The command code is not one this executive knows.
    UnknownCommand = 1,
    /// No control token was given.
    MissingToken = 2,
    /// The control token is not this stack's.
    WrongToken = 3,
    /// Another session is in control.
    OtherSessionInControl = 4,
    /// The current mode forbids the command.
    ForbiddenByMode = 5,
    /// The motion would leave the joint limits or the platform travel.
    OutsideLimits = 6,
    /// An argument is missing or malformed (arm number, joint, NaN).
    BadArgument = 7,
    /// The arm is in a picking cycle or moving.
    ArmBusy = 8,
    /// The arm's state is unknown or stale.
    ArmStateUnknown = 9,
    /// The motion would come closer to the other arm than the clearance.
    Clearance = 10,
    /// The device (platform) refused or is not present.
    Device = 11,
    /// The row's stop-and-go cycle refused "next stop" (an arm holds an apple, the platform
    /// or the trailer moves, the row is done, or no row is configured).
    Field = 12,
}

impl OperatorRefusalCode {
    /// Every refusal code, in code order.
    pub const ALL: [Self; 12] = [
        Self::UnknownCommand,
        Self::MissingToken,
        Self::WrongToken,
        Self::OtherSessionInControl,
        Self::ForbiddenByMode,
        Self::OutsideLimits,
        Self::BadArgument,
        Self::ArmBusy,
        Self::ArmStateUnknown,
        Self::Clearance,
        Self::Device,
        Self::Field,
    ];

    /// The refusal with this wire code; `None` for an unknown code.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|known| *known as u8 == code)
    }
}

/// One operator command (`operator/command`). `header.capture_ns` is when the client sent it.
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
#[type_name("harvest.OperatorCommand.v1")]
pub struct OperatorCommand {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// Chosen by the client, echoed in the acknowledgement (unique per session).
    pub request_id: u64,
    /// The client session (random per console page or `ctl` user); one session controls.
    pub session_id: u64,
    /// [`OperatorCommandCode`] code.
    pub code: u16,
    /// Arm 1 or 2 (arm commands), else 0.
    pub arm_id: u8,
    /// Joint index 0-3 (`D`, `theta`, `phi`, twist) of a jog, else 0.
    pub joint: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 4],
    /// Jog delta, m (joint 0) or rad.
    pub value: f64,
    /// Platform target `[in_out, up_down]`, m.
    pub platform_target_m: [f64; 2],
    /// The control token `harvest up` printed.
    pub token: FixedString<OPERATOR_TOKEN_BYTES>,
    /// Who sends it, for people: `console 127.0.0.1`, `ctl root`.
    pub client: FixedString<OPERATOR_CLIENT_BYTES>,
}

impl OperatorCommand {
    /// The typed command, `None` for an unknown code.
    pub fn command_code(&self) -> Option<OperatorCommandCode> {
        OperatorCommandCode::from_code(self.code)
    }
}

/// The executive's answer to one command (`operator/ack`).
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
#[type_name("harvest.OperatorAck.v1")]
pub struct OperatorAck {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// The command's `request_id`.
    pub request_id: u64,
    /// The command's `session_id`.
    pub session_id: u64,
    /// The command's code, as received.
    pub code: u16,
    /// 1 accepted, 0 refused.
    pub accepted: u8,
    /// [`OperatorRefusalCode`] code (0 when accepted).
    pub refusal: u8,
    /// [`OperatorModeCode`] after the command.
    pub mode: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 3],
    /// Planned duration of the motion the command started (0: none), ms.
    pub motion_duration_ms: u32,
    /// Zero; keeps the following fields aligned.
    pub _reserved2: [u8; 4],
    /// In words: what was done, or why not.
    pub reason: FixedString<OPERATOR_REASON_BYTES>,
}

/// The stack's operating mode (`operator/mode`, latched, re-sent at 10 Hz).
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
#[type_name("harvest.OperatorModeState.v1")]
pub struct OperatorModeState {
    /// Sequence number, capture and publish stamps (ns, stack clock); see [`Header`].
    pub header: Header,
    /// [`OperatorModeCode`] code.
    pub mode: u8,
    /// 1 while the emergency stop is engaged.
    pub emergency_stop_engaged: u8,
    /// 1 per arm that takes part in the harvest.
    pub arms_enabled: [u8; 2],
    /// 1 while the platform stages move.
    pub platform_in_motion: u8,
    /// 1 when the executive drives a platform and `platform_position_m` is its feedback.
    pub platform_present: u8,
    /// 1 while the row's stop-and-go cycle holds new approaches (the trailer drives, the arms
    /// park, the platform repositions, fresh detections are awaited): the vacuum supervisor
    /// dispatches no new target, the running attempts finish.
    pub field_hold: u8,
    /// Zero; keeps the following fields aligned.
    pub _reserved: [u8; 1],
    /// The controlling session (0: none).
    pub controlling_session: u64,
    /// When the mode (or the controller) last changed, ns.
    pub last_change_ns: u64,
    /// Platform stages `[in_out, up_down]`, m.
    pub platform_position_m: [f64; 2],
    /// Command code behind the last change (0: none, e.g. heartbeat lost).
    pub last_change_code: u16,
    /// Zero; keeps the following fields aligned.
    pub _reserved2: [u8; 6],
    /// The controlling session's client label.
    pub controller: FixedString<OPERATOR_CLIENT_BYTES>,
    /// In words: why the mode last changed.
    pub last_change_reason: FixedString<OPERATOR_REASON_BYTES>,
}

impl OperatorModeState {
    /// The typed mode, `None` before the first publication or for an unknown code.
    pub fn mode_code(&self) -> Option<OperatorModeCode> {
        OperatorModeCode::from_code(self.mode)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_unknown_codes_are_none() {
        for code in OperatorCommandCode::ALL {
            assert_eq!(OperatorCommandCode::from_code(code as u16), Some(code));
        }
        assert_eq!(OperatorCommandCode::from_code(0), None);
        assert_eq!(OperatorCommandCode::from_code(999), None);
        for mode in OperatorModeCode::ALL {
            assert_eq!(OperatorModeCode::from_code(mode as u8), Some(mode));
        }
        assert_eq!(OperatorModeCode::from_code(0), None);
        for refusal in OperatorRefusalCode::ALL {
            assert_eq!(OperatorRefusalCode::from_code(refusal as u8), Some(refusal));
        }
    }

    #[test]
    fn layouts_have_no_padding() {
        // Header 24 B + fields, every field at its natural alignment.
        assert_eq!(std::mem::size_of::<OperatorCommand>(), 72 + 64 + 32);
        assert_eq!(std::mem::size_of::<OperatorAck>(), 56 + 128);
        assert_eq!(std::mem::size_of::<OperatorModeState>(), 72 + 32 + 128);
    }
}
