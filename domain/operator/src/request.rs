//! The console's command requests: the JSON a page posts (`{"command": "jog", "arm": 1,
//! "joint": "theta", "delta": 0.05}`), turned into a [`Command`]. A request the console cannot
//! turn into a command is refused by the console itself, with the words of [`RequestError`].

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::command::{Command, JointName};

/// One request as posted (and as the remote link's station sends it inside its request).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommandRequest {
    /// The command's name (`start`, `pause`, ..., as [`Command::name`] spells it).
    pub command: String,
    /// Arm 1 or 2 (`arm-enable`, `arm-disable`, `jog`, `drop-off`).
    #[serde(default)]
    pub arm: Option<u8>,
    /// `d`, `theta`, `phi` or `twist` (`jog`).
    #[serde(default)]
    pub joint: Option<String>,
    /// m or rad (`jog`).
    #[serde(default)]
    pub delta: Option<f64>,
    /// m (`platform`).
    #[serde(default)]
    pub in_out_m: Option<f64>,
    /// m (`platform`).
    #[serde(default)]
    pub up_down_m: Option<f64>,
}

/// Why a request is not a command.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RequestError {
    /// The name is not a command.
    #[error("unknown command `{0}`")]
    UnknownCommand(String),
    /// A needed field is missing.
    #[error("`{command}` needs `{field}`")]
    Missing {
        command: &'static str,
        field: &'static str,
    },
    /// The joint name is not one of the four.
    #[error("unknown joint `{0}` (d, theta, phi, twist)")]
    UnknownJoint(String),
}

impl CommandRequest {
    /// The command asked for.
    pub fn to_command(&self) -> Result<Command, RequestError> {
        let arm = |command: &'static str| {
            self.arm.ok_or(RequestError::Missing {
                command,
                field: "arm",
            })
        };
        Ok(match self.command.as_str() {
            "start" => Command::Start,
            "pause" => Command::Pause,
            "resume" => Command::Resume,
            "stop" => Command::Stop,
            "estop" => Command::EmergencyStop,
            "release" => Command::Release,
            "home" => Command::Home,
            "heartbeat" => Command::Heartbeat,
            "leave-control" => Command::LeaveControl,
            "next-stop" => Command::NextStop,
            "arm-enable" => Command::SetArmEnabled {
                arm: arm("arm-enable")?,
                enabled: true,
            },
            "arm-disable" => Command::SetArmEnabled {
                arm: arm("arm-disable")?,
                enabled: false,
            },
            "drop-off" => Command::DropOff {
                arm: arm("drop-off")?,
            },
            "jog" => {
                let name = self.joint.as_deref().ok_or(RequestError::Missing {
                    command: "jog",
                    field: "joint",
                })?;
                Command::Jog {
                    arm: arm("jog")?,
                    joint: JointName::parse(name)
                        .ok_or_else(|| RequestError::UnknownJoint(name.to_owned()))?,
                    delta: self.delta.ok_or(RequestError::Missing {
                        command: "jog",
                        field: "delta",
                    })?,
                }
            }
            "platform" => Command::PlatformMove {
                target_m: [
                    self.in_out_m.ok_or(RequestError::Missing {
                        command: "platform",
                        field: "in_out_m",
                    })?,
                    self.up_down_m.ok_or(RequestError::Missing {
                        command: "platform",
                        field: "up_down_m",
                    })?,
                ],
            },
            other => return Err(RequestError::UnknownCommand(other.to_owned())),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> Result<Command, RequestError> {
        serde_json::from_str::<CommandRequest>(json)
            .expect("json")
            .to_command()
    }

    #[test]
    fn requests_become_commands() {
        assert_eq!(parse(r#"{"command":"pause"}"#), Ok(Command::Pause));
        assert_eq!(
            parse(r#"{"command":"jog","arm":2,"joint":"phi","delta":-0.1}"#),
            Ok(Command::Jog {
                arm: 2,
                joint: JointName::Phi,
                delta: -0.1
            })
        );
        assert_eq!(
            parse(r#"{"command":"platform","in_out_m":0.1,"up_down_m":0.3}"#),
            Ok(Command::PlatformMove {
                target_m: [0.1, 0.3]
            })
        );
        // Every command name the wire knows is a request name too.
        for code in harvest_ipc::payloads::OperatorCommandCode::ALL {
            let json = format!(
                r#"{{"command":"{}","arm":1,"joint":"d","delta":0.01,"in_out_m":0,"up_down_m":0}}"#,
                code.name()
            );
            assert_eq!(parse(&json).map(|c| c.code()), Ok(code));
        }
    }

    #[test]
    fn bad_requests_say_what_is_wrong() {
        assert_eq!(
            parse(r#"{"command":"fly"}"#),
            Err(RequestError::UnknownCommand("fly".to_owned()))
        );
        assert_eq!(
            parse(r#"{"command":"jog","arm":1,"joint":"elbow","delta":0.1}"#),
            Err(RequestError::UnknownJoint("elbow".to_owned()))
        );
        assert_eq!(
            parse(r#"{"command":"drop-off"}"#),
            Err(RequestError::Missing {
                command: "drop-off",
                field: "arm"
            })
        );
        assert!(serde_json::from_str::<CommandRequest>(r#"{"command":"start","x":1}"#).is_err());
    }
}
