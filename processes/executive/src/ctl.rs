//! `harvest ctl`: the operator's commands from a terminal (over SSH with nothing else than the
//! stack). Each command is sent on `operator/command` with the control token and the answer
//! on `operator/ack` is printed; the exit code is 0 when accepted, 1 when refused, 2 when no
//! answer came (is the executive running?). `status` reads `operator/mode`, the arms' and the
//! vacuum's state; it needs no token. Neither does `estop`: without a token (no file, none
//! given, or a malformed one) it is sent without one, and the executive stops the robot all the
//! same (a stop needs no authority).
//!
//! A manual move (jog, drop-off, home, platform) keeps this session's heartbeat going until the
//! move's planned time is over (or the platform stops), since the executive stops manual
//! motion when the controlling session is silent for 500 ms.
//!
//! The session id of `ctl` is the same for every run by one user in one domain, so commands
//! given one after the other belong to one session.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{ARM_STATE, OPERATOR_MARK, OPERATOR_MODE, VACUUM_STATE};
use harvest_ipc::fixed_string::FixedString;
use harvest_ipc::operator_client::{OperatorClient, OperatorClientError};
use harvest_ipc::payloads::{
    OperatorAck, OperatorModeCode, OperatorModeState, OperatorRefusalCode,
};
use harvest_ipc::{Context, Domain, MonotonicClock, Payload, Subscriber};
use harvest_operator::token::{TokenError, read_token_file, token_path};
use harvest_operator::{Command, ControlToken, JointName};

/// `harvest ctl` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct CtlArgs {
    /// Control token (default: read from the domain's token file, see `harvest up`).
    #[arg(long, global = true)]
    pub token: Option<String>,
    /// Token file (default: `$XDG_RUNTIME_DIR/harvest/<domain>.token`, else
    /// `/tmp/harvest-<uid>/<domain>.token`).
    #[arg(long, global = true)]
    pub token_file: Option<PathBuf>,
    /// How long to wait for the executive's answer, ms.
    #[arg(long, global = true, default_value_t = 2000)]
    pub timeout_ms: u64,
    /// Command ROBOT over the Zenoh link (`harvest remote` on the robot) instead of the stack
    /// of this machine's domain; the token file then defaults to `<ROBOT>.token` in the token
    /// directory. With `--link FILE`, `--connect ENDPOINT` (default `tcp/127.0.0.1:7447`).
    #[arg(long, global = true, value_name = "ROBOT")]
    pub remote: Option<String>,
    #[command(subcommand)]
    pub command: CtlCommand,
}

/// What `harvest ctl` does.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum CtlCommand {
    /// The mode, the arms, the vacuum (no token needed).
    Status {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Start harvesting.
    Start,
    /// Pause: no new approach; attempts under way finish.
    Pause,
    /// Resume after a pause.
    Resume,
    /// Stop harvesting (or manual motion): idle.
    Stop,
    /// Engage the emergency stop (a protective stop; the hardware e-stop stays the certified
    /// one). Needs no token: accepted from anyone, even while another session controls.
    Estop,
    /// Release the emergency stop.
    Release,
    /// Both arms to their home (drop-off) pose.
    Home,
    /// Enable or disable one arm: `arm 2 disable`.
    Arm {
        /// 1 or 2.
        #[arg(value_parser = clap::value_parser!(u8).range(1..=2))]
        number: u8,
        /// `enable` or `disable`.
        action: ArmAction,
    },
    /// Move one joint by a small amount (m for d, rad for the others).
    Jog {
        /// 1 or 2.
        #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2))]
        arm: u8,
        /// d, theta, phi or twist.
        #[arg(long, value_parser = parse_joint)]
        joint: JointName,
        /// m or rad (negative allowed).
        #[arg(long, allow_hyphen_values = true)]
        delta: f64,
    },
    /// Send one arm to its drop-off pose.
    DropOff {
        /// 1 or 2.
        #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2))]
        arm: u8,
    },
    /// Move the platform stages (m from their stops).
    Platform {
        /// In-out target, m.
        #[arg(long)]
        in_out: f64,
        /// Up-down target, m.
        #[arg(long)]
        up_down: f64,
    },
    /// Give up control (another session may take it at once).
    Leave,
    /// End the harvest at the row's current stop and advance to the next one (refused while
    /// an arm holds an apple, the platform or the trailer moves, the row is done, or the
    /// executive works no row).
    NextStop,
    /// Mark this moment (`operator/mark`, no token needed: a mark commands nothing): the
    /// recorder keeps a clip of its flight recorder around it and lists the mark in the
    /// recording's events.
    Mark {
        /// What happened, in a few words (cut at 120 bytes).
        text: String,
    },
}

/// `enable` or `disable`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ArmAction {
    Enable,
    Disable,
}

fn parse_joint(text: &str) -> Result<JointName, String> {
    JointName::parse(text).ok_or_else(|| format!("unknown joint `{text}`: d, theta, phi or twist"))
}

/// Why `harvest ctl` could not ask.
#[derive(Debug, thiserror::Error)]
pub enum CtlError {
    #[error(transparent)]
    Token(#[from] TokenError),
    #[error(transparent)]
    Client(#[from] OperatorClientError),
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(CtlError);

/// Exit code of a refused command.
const EXIT_REFUSED: u8 = 1;
/// Exit code when no answer came.
const EXIT_NO_ANSWER: u8 = 2;
/// Heartbeat period while a manual move runs.
const HEARTBEAT_PERIOD: Duration = Duration::from_millis(100);
/// Longest a platform move is accompanied.
const PLATFORM_MAX_WAIT: Duration = Duration::from_secs(60);

impl CtlCommand {
    /// The operator command, `None` for `status` and `mark` (no command).
    pub fn to_command(&self) -> Option<Command> {
        Some(match *self {
            Self::Status { .. } | Self::Mark { .. } => return None,
            Self::Start => Command::Start,
            Self::Pause => Command::Pause,
            Self::Resume => Command::Resume,
            Self::Stop => Command::Stop,
            Self::Estop => Command::EmergencyStop,
            Self::Release => Command::Release,
            Self::Home => Command::Home,
            Self::Arm { number, action } => Command::SetArmEnabled {
                arm: number,
                enabled: action == ArmAction::Enable,
            },
            Self::Jog { arm, joint, delta } => Command::Jog { arm, joint, delta },
            Self::DropOff { arm } => Command::DropOff { arm },
            Self::Platform { in_out, up_down } => Command::PlatformMove {
                target_m: [in_out, up_down],
            },
            Self::Leave => Command::LeaveControl,
            Self::NextStop => Command::NextStop,
        })
    }
}

/// The ctl session id: one per user and domain (FNV-1a of both).
fn session_id(domain: &Domain) -> u64 {
    let uid = std::fs::metadata("/proc/self").map_or(0, |meta| {
        use std::os::unix::fs::MetadataExt;
        meta.uid()
    });
    format!("ctl:{uid}:{}", domain.name())
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |hash, byte| {
            (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        })
        .max(1)
}

fn client_label() -> String {
    let user = std::env::var("USER").unwrap_or_else(|_| "user".to_owned());
    format!("ctl {user}")
}

/// The control token: `--token`, else the token file (default: `token_name`'s, the domain's
/// or, with `--remote`, the robot's).
pub fn control_token(args: &CtlArgs, token_name: &str) -> Result<ControlToken, TokenError> {
    match &args.token {
        Some(text) => ControlToken::parse(text, "--token"),
        None => {
            let path = args
                .token_file
                .clone()
                .unwrap_or_else(|| token_path(token_name));
            read_token_file(&path)
        }
    }
}

/// Runs `harvest ctl`.
pub fn run(args: &CtlArgs, domain: &Domain) -> Result<ExitCode, CtlError> {
    let context = Context::new(domain, &format!("ctl-{}", std::process::id()))?;
    let timeout = Duration::from_millis(args.timeout_ms);
    let Some(command) = args.command.to_command() else {
        return match &args.command {
            CtlCommand::Status { json } => status(&context, *json, timeout),
            CtlCommand::Mark { text } => mark(&context, text),
            _ => Ok(ExitCode::SUCCESS),
        };
    };
    let token = match (control_token(args, domain.name()), command) {
        (Ok(token), _) => token.as_str().to_owned(),
        // A stop needs no authority: without a (valid) token it is sent without one.
        (Err(error), Command::EmergencyStop) => {
            eprintln!("estop: no control token ({error}); sent without it (a stop needs none)");
            String::new()
        }
        (Err(error), _) => return Err(error.into()),
    };
    let session = session_id(domain);
    let client = client_label();
    let mut operator = OperatorClient::new(&context)?;
    let request = operator.send(command.to_message(0, session, &token, &client))?;
    let Some(ack) = operator.wait_ack(session, request, timeout)? else {
        eprintln!(
            "{}: no answer within {} ms (is `harvest executive` running in domain {domain}?)",
            command.name(),
            args.timeout_ms
        );
        return Ok(ExitCode::from(EXIT_NO_ANSWER));
    };
    print_ack(command.name(), &ack);
    if ack.accepted == 0 {
        return Ok(ExitCode::from(EXIT_REFUSED));
    }
    // Accompany a manual move with heartbeats.
    let platform = matches!(command, Command::PlatformMove { .. });
    if ack.motion_duration_ms > 0 || platform {
        let until = Instant::now()
            + if platform {
                PLATFORM_MAX_WAIT
            } else {
                Duration::from_millis(u64::from(ack.motion_duration_ms) + 300)
            };
        let mode_in = context.subscriber(OPERATOR_MODE)?;
        let mut moving_seen = false;
        while Instant::now() < until {
            std::thread::sleep(HEARTBEAT_PERIOD);
            let beat = operator.send(Command::Heartbeat.to_message(0, session, &token, &client))?;
            if let Some(ack) = operator.wait_ack(session, beat, timeout)?
                && ack.accepted == 0
            {
                print_ack("heartbeat", &ack);
                return Ok(ExitCode::from(EXIT_REFUSED));
            }
            if platform && let Some(mode) = mode_in.receive_latest()? {
                moving_seen |= mode.platform_in_motion != 0;
                if moving_seen && mode.platform_in_motion == 0 {
                    break;
                }
            }
        }
        println!("{}: motion done", command.name());
    }
    Ok(ExitCode::SUCCESS)
}

/// How long `ctl mark` keeps its publisher after sending: the sample lives in the publisher's
/// shared memory, so the recorder must have taken it before this process ends (it wakes on the
/// mark's event within a millisecond; the margin covers a loaded machine).
const MARK_LINGER: Duration = Duration::from_millis(300);

/// Publishes one mark on `operator/mark`.
fn mark(context: &Context, text: &str) -> Result<ExitCode, CtlError> {
    let mut publisher = context.publisher(OPERATOR_MARK)?;
    let marked_ns = MonotonicClock::read_ns();
    publisher.publish_with(marked_ns, |mark| {
        mark.text = FixedString::new(text);
        mark.source = FixedString::new(&client_label());
    })?;
    println!("mark: sent {text:?}");
    std::thread::sleep(MARK_LINGER);
    Ok(ExitCode::SUCCESS)
}

fn print_ack(name: &str, ack: &OperatorAck) {
    let mode = OperatorModeCode::from_code(ack.mode).map_or("?", OperatorModeCode::name);
    if ack.accepted != 0 {
        let duration = if ack.motion_duration_ms > 0 {
            format!(" ({:.1} s)", f64::from(ack.motion_duration_ms) / 1000.0)
        } else {
            String::new()
        };
        println!("{name}: accepted: {}{duration} [mode {mode}]", ack.reason);
    } else {
        let code = OperatorRefusalCode::from_code(ack.refusal)
            .map_or_else(|| format!("code {}", ack.refusal), |c| format!("{c:?}"));
        eprintln!("{name}: refused ({code}): {} [mode {mode}]", ack.reason);
    }
}

/// The newest latched sample of a state channel, waiting up to `timeout` for the first.
fn latest<T: Payload + Copy>(
    subscriber: &Subscriber<T>,
    timeout: Duration,
) -> Result<Option<T>, CtlError> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(sample) = subscriber.receive_latest()? {
            return Ok(Some(*sample));
        }
        let now = Instant::now();
        if now >= deadline {
            return Ok(None);
        }
        let _ = subscriber.listener().timed_wait(|_| {}, deadline - now);
    }
}

fn status(context: &Context, json: bool, timeout: Duration) -> Result<ExitCode, CtlError> {
    let mode_in = context.subscriber(OPERATOR_MODE)?;
    let arms_in = [
        context.subscriber(ARM_STATE[0])?,
        context.subscriber(ARM_STATE[1])?,
    ];
    let vacuum_in = context.subscriber(VACUUM_STATE)?;
    let mode: Option<OperatorModeState> = latest(&mode_in, timeout)?;
    let short = Duration::from_millis(300);
    let arms = [latest(&arms_in[0], short)?, latest(&arms_in[1], short)?];
    let vacuum = latest(&vacuum_in, short)?;
    let now_ns = MonotonicClock::read_ns();
    // Written at once, and a closed pipe (`| head`) is no error.
    let mut out = String::new();
    if json {
        let value = serde_json::json!({
            "mode": mode.and_then(|m| m.mode_code()).map(OperatorModeCode::name),
            "operator": mode.map(|m| m.to_json()),
            "arms": arms.map(|a| a.map(|a| serde_json::json!({
                "phase": a.phase.get().ok().map(|p| format!("{p:?}").to_lowercase()),
                "apple_id": a.apple_id,
                "harvested": a.harvested_count,
                "joint_position": a.joint_position,
                "age_ms": now_ns.saturating_sub(a.header.capture_ns) / 1_000_000,
            }))),
            "vacuum": vacuum.map(|v| v.to_json()),
        });
        _ = writeln!(out, "{value}");
    } else {
        match mode {
            Some(m) => {
                let name = m.mode_code().map_or("?", OperatorModeCode::name);
                _ = writeln!(
                    out,
                    "mode {name}; arms enabled {}/{}; e-stop {}; controller {}; last change: {}",
                    m.arms_enabled[0],
                    m.arms_enabled[1],
                    if m.emergency_stop_engaged != 0 {
                        "ENGAGED"
                    } else {
                        "released"
                    },
                    if m.controlling_session == 0 {
                        "none"
                    } else {
                        m.controller.as_str()
                    },
                    m.last_change_reason
                );
                if m.platform_present != 0 {
                    _ = writeln!(
                        out,
                        "platform {:.3} m in-out, {:.3} m up-down{}",
                        m.platform_position_m[0],
                        m.platform_position_m[1],
                        if m.platform_in_motion != 0 {
                            ", moving"
                        } else {
                            ""
                        }
                    );
                }
            }
            None => {
                _ = writeln!(
                    out,
                    "mode unknown: no executive answered within {} ms",
                    timeout.as_millis()
                )
            }
        }
        for (i, arm) in arms.iter().enumerate() {
            match arm {
                Some(a) => {
                    _ = writeln!(
                        out,
                        "arm {}: {} apple {} harvested {}",
                        i + 1,
                        a.phase
                            .get()
                            .map_or_else(|_| "?".to_owned(), |p| format!("{p:?}").to_lowercase()),
                        a.apple_id,
                        a.harvested_count
                    )
                }
                None => _ = writeln!(out, "arm {}: no state", i + 1),
            }
        }
        if let Some(v) = vacuum {
            _ = writeln!(
                out,
                "valves {:?}; vacuum arm1 {:.0} arm2 {:.0} source {:.0} mmH2O",
                v.valve_open, v.pressure_mmh2o[0], v.pressure_mmh2o[1], v.pressure_mmh2o[2]
            );
        }
    }
    let _ = std::io::Write::write_all(&mut std::io::stdout(), out.as_bytes());
    Ok(if mode.is_some() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(EXIT_NO_ANSWER)
    })
}
