//! The typed operator commands: decoded from an `operator/command` sample by the executive,
//! encoded into one by the clients. The wire code is [`OperatorCommandCode`]; a code this build
//! does not know is a [`Refusal::UnknownCommand`], never a guess.

use harvest_ipc::FixedString;
use harvest_ipc::payloads::{OperatorCommand, OperatorCommandCode};
use serde::{Deserialize, Serialize};

use crate::refusal::Refusal;

/// One joint of a tube arm (index in `[D, theta, phi, twist]` arrays).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointName {
    /// Prismatic extension, m.
    D,
    /// Pitch, rad.
    Theta,
    /// Yaw, rad.
    Phi,
    /// End-effector twist, rad.
    Twist,
}

impl JointName {
    pub const ALL: [Self; 4] = [Self::D, Self::Theta, Self::Phi, Self::Twist];

    /// Index in joint arrays.
    pub fn index(self) -> usize {
        match self {
            Self::D => 0,
            Self::Theta => 1,
            Self::Phi => 2,
            Self::Twist => 3,
        }
    }

    /// The joint of index `index`.
    pub fn from_index(index: u8) -> Option<Self> {
        Self::ALL.get(usize::from(index)).copied()
    }

    /// `d`, `theta`, `phi`, `twist`.
    pub fn name(self) -> &'static str {
        match self {
            Self::D => "d",
            Self::Theta => "theta",
            Self::Phi => "phi",
            Self::Twist => "twist",
        }
    }

    /// The joint named `name` (as [`Self::name`] spells it).
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|joint| joint.name() == name)
    }

    /// `m` for the prismatic joint, `rad` for the others.
    pub fn unit(self) -> &'static str {
        match self {
            Self::D => "m",
            _ => "rad",
        }
    }
}

/// What the operator asks for, with its arguments.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    Start,
    Pause,
    Resume,
    Stop,
    EmergencyStop,
    Release,
    Home,
    /// Arm 1 or 2 takes part in the harvest (`true`) or gets no new apple (`false`).
    SetArmEnabled {
        arm: u8,
        enabled: bool,
    },
    /// Move one joint of one arm by `delta` (m or rad).
    Jog {
        arm: u8,
        joint: JointName,
        delta: f64,
    },
    /// Send one arm to its drop-off pose.
    DropOff {
        arm: u8,
    },
    /// Move the platform stages to `[in_out, up_down]`, m.
    PlatformMove {
        target_m: [f64; 2],
    },
    Heartbeat,
    LeaveControl,
    /// End the harvest at the row's current stop and advance to the next one.
    NextStop,
}

fn arm_argument(arm_id: u8) -> Result<u8, Refusal> {
    match arm_id {
        1 | 2 => Ok(arm_id),
        other => Err(Refusal::BadArgument(format!(
            "arm {other}: expected 1 or 2"
        ))),
    }
}

impl Command {
    /// The wire code.
    pub fn code(&self) -> OperatorCommandCode {
        match self {
            Self::Start => OperatorCommandCode::Start,
            Self::Pause => OperatorCommandCode::Pause,
            Self::Resume => OperatorCommandCode::Resume,
            Self::Stop => OperatorCommandCode::Stop,
            Self::EmergencyStop => OperatorCommandCode::EmergencyStop,
            Self::Release => OperatorCommandCode::Release,
            Self::Home => OperatorCommandCode::Home,
            Self::SetArmEnabled { enabled: true, .. } => OperatorCommandCode::ArmEnable,
            Self::SetArmEnabled { enabled: false, .. } => OperatorCommandCode::ArmDisable,
            Self::Jog { .. } => OperatorCommandCode::Jog,
            Self::DropOff { .. } => OperatorCommandCode::DropOff,
            Self::PlatformMove { .. } => OperatorCommandCode::PlatformMove,
            Self::Heartbeat => OperatorCommandCode::Heartbeat,
            Self::LeaveControl => OperatorCommandCode::LeaveControl,
            Self::NextStop => OperatorCommandCode::NextStop,
        }
    }

    /// The command name (`harvest ctl` spelling).
    pub fn name(&self) -> &'static str {
        self.code().name()
    }

    /// The command of a received sample: unknown codes and malformed arguments are refusals.
    pub fn decode(message: &OperatorCommand) -> Result<Self, Refusal> {
        let code = message
            .command_code()
            .ok_or(Refusal::UnknownCommand(message.code))?;
        Ok(match code {
            OperatorCommandCode::Start => Self::Start,
            OperatorCommandCode::Pause => Self::Pause,
            OperatorCommandCode::Resume => Self::Resume,
            OperatorCommandCode::Stop => Self::Stop,
            OperatorCommandCode::EmergencyStop => Self::EmergencyStop,
            OperatorCommandCode::Release => Self::Release,
            OperatorCommandCode::Home => Self::Home,
            OperatorCommandCode::ArmEnable | OperatorCommandCode::ArmDisable => {
                Self::SetArmEnabled {
                    arm: arm_argument(message.arm_id)?,
                    enabled: code == OperatorCommandCode::ArmEnable,
                }
            }
            OperatorCommandCode::Jog => {
                let joint = JointName::from_index(message.joint).ok_or_else(|| {
                    Refusal::BadArgument(format!(
                        "joint {}: expected 0-3 (d, theta, phi, twist)",
                        message.joint
                    ))
                })?;
                if !message.value.is_finite() {
                    return Err(Refusal::BadArgument(format!(
                        "jog delta {} is not a number",
                        message.value
                    )));
                }
                Self::Jog {
                    arm: arm_argument(message.arm_id)?,
                    joint,
                    delta: message.value,
                }
            }
            OperatorCommandCode::DropOff => Self::DropOff {
                arm: arm_argument(message.arm_id)?,
            },
            OperatorCommandCode::PlatformMove => Self::PlatformMove {
                target_m: message.platform_target_m,
            },
            OperatorCommandCode::Heartbeat => Self::Heartbeat,
            OperatorCommandCode::LeaveControl => Self::LeaveControl,
            OperatorCommandCode::NextStop => Self::NextStop,
        })
    }

    /// The sample a client sends (its header is stamped by the transport and the caller).
    pub fn to_message(
        &self,
        request_id: u64,
        session_id: u64,
        token: &str,
        client: &str,
    ) -> OperatorCommand {
        let mut message = OperatorCommand {
            request_id,
            session_id,
            code: self.code() as u16,
            token: FixedString::new(token),
            client: FixedString::new(client),
            ..OperatorCommand::default()
        };
        match *self {
            Self::SetArmEnabled { arm, .. } | Self::DropOff { arm } => message.arm_id = arm,
            Self::Jog { arm, joint, delta } => {
                message.arm_id = arm;
                message.joint = joint.index() as u8;
                message.value = delta;
            }
            Self::PlatformMove { target_m } => message.platform_target_m = target_m,
            _ => {}
        }
        message
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_command_survives_the_wire() {
        let commands = [
            Command::Start,
            Command::Pause,
            Command::Resume,
            Command::Stop,
            Command::EmergencyStop,
            Command::Release,
            Command::Home,
            Command::SetArmEnabled {
                arm: 2,
                enabled: false,
            },
            Command::SetArmEnabled {
                arm: 1,
                enabled: true,
            },
            Command::Jog {
                arm: 1,
                joint: JointName::Phi,
                delta: -0.05,
            },
            Command::DropOff { arm: 2 },
            Command::PlatformMove {
                target_m: [0.1, 0.2],
            },
            Command::Heartbeat,
            Command::LeaveControl,
            Command::NextStop,
        ];
        for command in commands {
            let message = command.to_message(7, 9, "token", "test");
            assert_eq!(message.token.as_str(), "token");
            assert_eq!(Command::decode(&message), Ok(command));
        }
    }

    #[test]
    fn unknown_codes_and_bad_arguments_are_refused() {
        let mut message = Command::Start.to_message(1, 1, "t", "test");
        message.code = 77;
        assert_eq!(Command::decode(&message), Err(Refusal::UnknownCommand(77)));
        let mut jog = Command::Jog {
            arm: 1,
            joint: JointName::D,
            delta: 0.01,
        }
        .to_message(1, 1, "t", "test");
        jog.joint = 4;
        assert!(matches!(
            Command::decode(&jog),
            Err(Refusal::BadArgument(_))
        ));
        jog.joint = 0;
        jog.arm_id = 3;
        assert!(matches!(
            Command::decode(&jog),
            Err(Refusal::BadArgument(_))
        ));
        jog.arm_id = 1;
        jog.value = f64::NAN;
        assert!(matches!(
            Command::decode(&jog),
            Err(Refusal::BadArgument(_))
        ));
    }
}
