//! Why a command was refused: one variant per reason, each with the words the operator reads
//! on the page and from `harvest ctl`.

use harvest_ipc::payloads::{OperatorModeCode, OperatorRefusalCode};
use thiserror::Error;

/// A refused command.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Refusal {
    /// The code is not one this executive knows: nothing is done.
    #[error("unknown command code {0}: nothing done")]
    UnknownCommand(u16),
    /// No token was sent.
    #[error("missing control token (printed by `harvest up`, in its token file)")]
    MissingToken,
    /// The token is not this stack's.
    #[error("wrong control token")]
    WrongToken,
    /// Another session holds control.
    #[error("{client} is in control (heard {age_ms} ms ago); it must leave control first")]
    OtherSessionInControl {
        /// The controlling client's label.
        client: String,
        /// Since its last command or heartbeat, ms.
        age_ms: u64,
    },
    /// The mode forbids the command.
    #[error("`{command}` is not allowed while {mode}{hint}")]
    ForbiddenByMode {
        /// The command's name.
        command: &'static str,
        /// The mode's name.
        mode: &'static str,
        /// What to do instead (starts with `: `, or empty).
        hint: &'static str,
    },
    /// A joint goal outside the Table 1 limits.
    #[error("arm {arm} {joint} goal {value:.3} outside the limits [{min:.3}, {max:.3}]")]
    JointOutsideLimits {
        /// Arm number.
        arm: u8,
        /// Joint name.
        joint: &'static str,
        /// The goal, m or rad.
        value: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
    },
    /// A platform target outside the travel.
    #[error("platform {axis} target {value:.3} m outside the travel [0, {max:.3}] m")]
    PlatformOutsideTravel {
        /// `in-out` or `up-down`.
        axis: &'static str,
        /// The target, m.
        value: f64,
        /// The stroke, m.
        max: f64,
    },
    /// A malformed argument.
    #[error("bad argument: {0}")]
    BadArgument(String),
    /// The arm is in a picking cycle or still moving.
    #[error("arm {arm} is busy ({what})")]
    ArmBusy {
        /// Arm number.
        arm: u8,
        /// Its phase or motion.
        what: String,
    },
    /// The arm's state is missing or stale.
    #[error("arm {0}: no recent state (is its process running?)")]
    ArmStateUnknown(u8),
    /// The move would come too close to the other arm.
    #[error(
        "arm {arm}: the move comes within {distance_m:.3} m of the other arm (clearance {clearance_m:.3} m)"
    )]
    Clearance {
        /// Arm number.
        arm: u8,
        /// Closest approach, m.
        distance_m: f64,
        /// Required clearance, m.
        clearance_m: f64,
    },
    /// No platform is driven by this executive.
    #[error("no platform device (the executive runs with `--platform none`)")]
    NoPlatform,
    /// "Next stop" without a row (the executive runs without `--row-stops`).
    #[error("no row configured (the executive runs without `--row-stops`)")]
    NoRow,
    /// The row's stop cycle refused "next stop" (its reason in words).
    #[error("next stop refused: {0}")]
    NextStop(String),
}

impl Refusal {
    /// The wire code of this refusal.
    pub fn code(&self) -> OperatorRefusalCode {
        match self {
            Self::UnknownCommand(_) => OperatorRefusalCode::UnknownCommand,
            Self::MissingToken => OperatorRefusalCode::MissingToken,
            Self::WrongToken => OperatorRefusalCode::WrongToken,
            Self::OtherSessionInControl { .. } => OperatorRefusalCode::OtherSessionInControl,
            Self::ForbiddenByMode { .. } => OperatorRefusalCode::ForbiddenByMode,
            Self::JointOutsideLimits { .. } | Self::PlatformOutsideTravel { .. } => {
                OperatorRefusalCode::OutsideLimits
            }
            Self::BadArgument(_) => OperatorRefusalCode::BadArgument,
            Self::ArmBusy { .. } => OperatorRefusalCode::ArmBusy,
            Self::ArmStateUnknown(_) => OperatorRefusalCode::ArmStateUnknown,
            Self::Clearance { .. } => OperatorRefusalCode::Clearance,
            Self::NoPlatform => OperatorRefusalCode::Device,
            Self::NoRow | Self::NextStop(_) => OperatorRefusalCode::Field,
        }
    }

    /// The refusal of `command` in `mode`, with a hint of what to do instead.
    pub fn forbidden(command: &'static str, mode: OperatorModeCode) -> Self {
        let hint = match (mode, command) {
            (OperatorModeCode::EmergencyStopped, _) => ": release the emergency stop first",
            (OperatorModeCode::Harvesting, "start" | "resume") => ": already harvesting",
            (OperatorModeCode::Harvesting, _) => ": pause or stop the harvest first",
            (OperatorModeCode::Paused, "pause") => ": already paused",
            (_, "pause" | "resume") => ": not harvesting (use start)",
            _ => "",
        };
        Self::ForbiddenByMode {
            command,
            mode: mode.name(),
            hint,
        }
    }
}
