//! `harvest ctl --remote ROBOT ...`: the operator's commands to a robot over the link, from the
//! station. The same commands as `harvest ctl`, the same exit codes (0 accepted, 1 refused,
//! 2 no answer), and the same rules: the control token goes with every command but the
//! e-stop (which goes on its own key and needs none), a manual move is accompanied by a
//! heartbeat every 100 ms until its planned time is over, so the executive stops the motion
//! within 500 ms when this station is lost; a heartbeat without an answer ends the command
//! with the no-answer code (the link is lost, the robot has stopped the motion). `status`
//! reads the robot's summary and mode.
//!
//! The station's session id is the same for every run by one user for one robot, so commands
//! given one after the other belong to one session (as with `harvest ctl`).

use std::process::ExitCode;
use std::time::{Duration, Instant};

use harvest_operator::{Command, ControlToken};
use harvest_remote::fleet_summary::FleetSummary;
use harvest_remote::remote_request::{RemoteReply, RemoteRequest};
use harvest_remote::{LinkSettings, RobotKeys, RobotName};
use serde_json::Value;
use zenoh::Wait;

use crate::error::RemoteError;
use crate::link_session::{LinkArgs, open_session};

/// Exit code of a refused command.
const EXIT_REFUSED: u8 = 1;
/// Exit code when no answer came.
const EXIT_NO_ANSWER: u8 = 2;
/// Heartbeat period while a manual move runs.
const HEARTBEAT_PERIOD: Duration = Duration::from_millis(100);
/// Longest a platform move is accompanied.
const PLATFORM_MAX_WAIT: Duration = Duration::from_secs(60);

/// What the station asks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ask {
    /// Print the robot's summary and mode (`--json`: one JSON object).
    Status { json: bool },
    /// Send a command.
    Command(Command),
}

/// The station's session with one robot.
pub struct Station {
    session: zenoh::Session,
    keys: RobotKeys,
    session_id: u64,
    client: String,
}

/// The station's session id for `robot`: one per user and robot (FNV-1a).
fn station_session_id(robot: &RobotName) -> u64 {
    let uid = std::fs::metadata("/proc/self").map_or(0, |meta| {
        use std::os::unix::fs::MetadataExt;
        meta.uid()
    });
    format!("station:{uid}:{robot}")
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |hash, byte| {
            (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        })
        .max(1)
}

impl Station {
    /// Opens the link to `robot`, whether or not the robot is there yet.
    pub fn open(robot: RobotName, link: &LinkArgs) -> Result<Self, RemoteError> {
        let settings = link.settings(LinkSettings::station_default())?;
        let session = open_session(&settings, harvest_remote::keys::ROOT)?;
        let user = std::env::var("USER").unwrap_or_else(|_| "user".to_owned());
        Ok(Self {
            session,
            session_id: station_session_id(&robot),
            keys: RobotKeys::new(robot),
            client: format!("station {user}"),
        })
    }

    /// Opens the link to `robot` and waits up to `timeout` until the robot is seen (its
    /// liveliness token); `None` if it is not.
    pub fn connect(
        robot: RobotName,
        link: &LinkArgs,
        timeout: Duration,
    ) -> Result<Option<Self>, RemoteError> {
        let station = Self::open(robot, link)?;
        let alive = station
            .session
            .liveliness()
            .declare_subscriber(station.keys.alive())
            .history(true)
            .wait()?;
        let seen = alive.recv_timeout(timeout).ok().flatten().is_some();
        Ok(seen.then_some(station))
    }

    /// Sends one command; the reply, `None` if none came within `timeout`.
    pub fn send(
        &self,
        command: Command,
        token: Option<&ControlToken>,
        timeout: Duration,
    ) -> Result<Option<RemoteReply>, RemoteError> {
        let request = RemoteRequest {
            session: self.session_id,
            token: token.map(|t| t.as_str().to_owned()),
            client: self.client.clone(),
            command: command_request(command),
        };
        self.send_request(&request, command == Command::EmergencyStop, timeout)
    }

    /// Sends `request` (on the e-stop's key when `estop`, else on the command key); the reply,
    /// `None` if none came within `timeout`.
    pub fn send_request(
        &self,
        request: &RemoteRequest,
        estop: bool,
        timeout: Duration,
    ) -> Result<Option<RemoteReply>, RemoteError> {
        let payload =
            serde_json::to_vec(request).map_err(|e| RemoteError::Invalid(e.to_string()))?;
        let key = if estop {
            self.keys.estop()
        } else {
            self.keys.command()
        };
        self.query(&key, payload, timeout)
    }

    /// A raw query (tests and benchmarks send malformed ones this way).
    pub fn query(
        &self,
        key: &str,
        payload: Vec<u8>,
        timeout: Duration,
    ) -> Result<Option<RemoteReply>, RemoteError> {
        let replies = self
            .session
            .get(key)
            .payload(payload)
            .timeout(timeout)
            .wait()?;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result()
                && let Ok(answer) =
                    serde_json::from_slice::<RemoteReply>(&sample.payload().to_bytes())
            {
                return Ok(Some(answer));
            }
        }
        Ok(None)
    }

    /// The newest sample of `suffix` within `timeout` (on-change keys beat every second).
    fn latest(&self, suffix: &str, timeout: Duration) -> Result<Option<Value>, RemoteError> {
        let subscriber = self
            .session
            .declare_subscriber(self.keys.key(suffix))
            .wait()?;
        let sample = subscriber.recv_timeout(timeout).ok().flatten();
        Ok(sample.and_then(|s| serde_json::from_slice(&s.payload().to_bytes()).ok()))
    }

    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    pub fn keys(&self) -> &RobotKeys {
        &self.keys
    }
}

/// The console's request for `command` (the wire of the link).
pub fn command_request(command: Command) -> harvest_operator::request::CommandRequest {
    let mut request = harvest_operator::request::CommandRequest {
        command: command.name().to_owned(),
        arm: None,
        joint: None,
        delta: None,
        in_out_m: None,
        up_down_m: None,
    };
    match command {
        Command::SetArmEnabled { arm, .. } | Command::DropOff { arm } => request.arm = Some(arm),
        Command::Jog { arm, joint, delta } => {
            request.arm = Some(arm);
            request.joint = Some(joint.name().to_owned());
            request.delta = Some(delta);
        }
        Command::PlatformMove { target_m } => {
            request.in_out_m = Some(target_m[0]);
            request.up_down_m = Some(target_m[1]);
        }
        _ => {}
    }
    request
}

fn print_reply(name: &str, reply: &RemoteReply) {
    let mode = reply.mode.as_deref().unwrap_or("?");
    if reply.accepted {
        let duration = if reply.motion_duration_ms > 0 {
            format!(" ({:.1} s)", f64::from(reply.motion_duration_ms) / 1000.0)
        } else {
            String::new()
        };
        println!("{name}: accepted: {}{duration} [mode {mode}]", reply.reason);
    } else {
        let code = reply.refusal.as_deref().unwrap_or("?");
        let by = match reply.by {
            harvest_remote::remote_request::Answerer::Remote => " by the link",
            harvest_remote::remote_request::Answerer::Executive => "",
        };
        eprintln!(
            "{name}: refused{by} ({code}): {} [mode {mode}]",
            reply.reason
        );
    }
}

/// Runs `harvest ctl --remote ROBOT ...`.
pub fn run(
    robot: RobotName,
    link: &LinkArgs,
    ask: Ask,
    token: Option<ControlToken>,
    timeout: Duration,
) -> Result<ExitCode, RemoteError> {
    let Some(station) = Station::connect(robot.clone(), link, timeout)? else {
        eprintln!(
            "robot `{robot}` not seen on the link within {} ms (is `harvest remote` running there, and --connect/--link right?)",
            timeout.as_millis()
        );
        return Ok(ExitCode::from(EXIT_NO_ANSWER));
    };
    let command = match ask {
        Ask::Status { json } => return status(&station, json, timeout),
        Ask::Command(command) => command,
    };
    if token.is_none() && command != Command::EmergencyStop {
        return Err(RemoteError::Invalid(format!(
            "{}: a control token is needed (--token or --token-file)",
            command.name()
        )));
    }
    let Some(reply) = station.send(command, token.as_ref(), timeout)? else {
        eprintln!(
            "{}: no answer within {} ms",
            command.name(),
            timeout.as_millis()
        );
        return Ok(ExitCode::from(EXIT_NO_ANSWER));
    };
    print_reply(command.name(), &reply);
    if !reply.accepted {
        return Ok(ExitCode::from(EXIT_REFUSED));
    }
    let platform = matches!(command, Command::PlatformMove { .. });
    if reply.motion_duration_ms > 0 || platform {
        let until = Instant::now()
            + if platform {
                PLATFORM_MAX_WAIT
            } else {
                Duration::from_millis(u64::from(reply.motion_duration_ms) + 300)
            };
        let mode = station
            .session
            .declare_subscriber(station.keys.key("state/mode"))
            .wait()?;
        let mut moving_seen = false;
        while Instant::now() < until {
            std::thread::sleep(HEARTBEAT_PERIOD);
            match station.send(Command::Heartbeat, token.as_ref(), timeout)? {
                Some(beat) if !beat.accepted => {
                    print_reply("heartbeat", &beat);
                    return Ok(ExitCode::from(EXIT_REFUSED));
                }
                Some(_) => {}
                // The robot has not heard this station for longer than its heartbeat timeout:
                // it has stopped the motion, and accompanying it further means nothing.
                None => {
                    eprintln!(
                        "{}: the heartbeat got no answer within {} ms: link lost; the robot stops a manual motion after 500 ms without heartbeats",
                        command.name(),
                        timeout.as_millis()
                    );
                    return Ok(ExitCode::from(EXIT_NO_ANSWER));
                }
            }
            if platform {
                while let Ok(Some(sample)) = mode.try_recv() {
                    let value: Value =
                        serde_json::from_slice(&sample.payload().to_bytes()).unwrap_or_default();
                    let moving = value["platform_in_motion"].as_u64().unwrap_or(0) != 0;
                    moving_seen |= moving;
                    if moving_seen && !moving {
                        println!("{}: motion done", command.name());
                        return Ok(ExitCode::SUCCESS);
                    }
                }
            }
        }
        println!("{}: motion done", command.name());
    }
    Ok(ExitCode::SUCCESS)
}

fn status(station: &Station, json: bool, timeout: Duration) -> Result<ExitCode, RemoteError> {
    let summary = station.latest(harvest_remote::keys::SUMMARY, timeout)?;
    let mode = station.latest("state/mode", timeout)?;
    if json {
        println!(
            "{}",
            serde_json::json!({ "summary": summary, "mode": mode })
        );
        return Ok(if summary.is_some() {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(EXIT_NO_ANSWER)
        });
    }
    let Some(summary) = summary.and_then(|s| serde_json::from_value::<FleetSummary>(s).ok()) else {
        eprintln!("status: no summary within {} ms", timeout.as_millis());
        return Ok(ExitCode::from(EXIT_NO_ANSWER));
    };
    let success = summary
        .success_rate
        .map_or_else(|| "-".to_owned(), |rate| format!("{:.0} %", rate * 100.0));
    println!(
        "robot {}: mode {}; e-stop {}; harvested {} of {} attempted (success {success}); alarms: {}",
        summary.robot,
        summary.mode,
        if summary.estop_engaged {
            "ENGAGED"
        } else {
            "released"
        },
        summary.apples_harvested,
        summary.apples_attempted,
        if summary.alarms.is_empty() {
            "none".to_owned()
        } else {
            summary.alarms.join("; ")
        },
    );
    if let Some(mode) = mode {
        println!(
            "controller: {}; last change: {}",
            mode["controller"]
                .as_str()
                .filter(|c| !c.is_empty())
                .unwrap_or("none"),
            mode["last_change_reason"].as_str().unwrap_or("")
        );
    }
    Ok(ExitCode::SUCCESS)
}
