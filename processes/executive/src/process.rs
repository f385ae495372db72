//! `harvest executive`: the operator's mode machine over the channels.
//!
//! Per tick (a wait-set interval of `--control-period-us`, 200 Hz by default, never a sleep):
//! 1. the newest state of each arm and, every 100 ms, the platform's position are taken;
//! 2. a violation on `safety/violation` whose action is `stop` (the independent safety monitor,
//!    `harvest monitor --on-violation stop`) engages the protective stop
//!    ([`Executive::protective_stop`]; release stays an operator command); then every command on
//!    `operator/command` goes through [`Executive::handle`]; its actions are
//!    carried out (e-stop engage/release on `safety/emergency_stop`, manual orders on
//!    `armN/manual`, platform moves through the [`Platform`] trait) before the acknowledgement
//!    goes out on `operator/ack` (a platform that refuses turns it into a refusal; "next stop"
//!    goes to the row's stop cycle, whose refusal becomes the acknowledgement's);
//! 3. [`Executive::tick`] stops a manual motion whose controlling session went silent;
//! 4. `operator/mode` is published on every change and at 10 Hz.
//!
//! So an e-stop command reaches `safety/emergency_stop` within one executive period of its
//! arrival, and the arms and the vacuum supervisor obey it at their next tick.
//!
//! At start the executive waits up to 200 ms for the arms' states: an arm that reports itself
//! stopped sees an engaged e-stop (from an earlier executive), so the executive starts
//! e-stopped and publishes it again; the e-stop is never released implicitly. The mode and the
//! enabled arms of an earlier executive of the same `harvest up` run come back from the mode
//! file (`harvest_operator::mode_file`), so a crash does not resume a paused harvest.
//!
//! The control token comes from `$HARVEST_CONTROL_TOKEN` (set by `harvest up`), else from the
//! domain's token file.

use std::path::PathBuf;
use std::time::Duration;

use crate::row::{RowLink, RowOptions};
use harvest_field::StopCycleError;
use harvest_hw::platform::sim::SimPlatform;
use harvest_hw::platform::{Platform, PlatformTravel};
use harvest_hw::{AnyDeviceError, DeviceError};
use harvest_ipc::catalogue::{
    ARM_MANUAL, ARM_STATE, EMERGENCY_STOP, OPERATOR_ACK, OPERATOR_COMMAND, OPERATOR_MODE,
    SAFETY_VIOLATION,
};
use harvest_ipc::control_loop::{Wake, run_control_loop};
use harvest_ipc::payloads::{
    ArmManualKind, ArmPhase, ArmState, DeviceErrorCode, OperatorCommand, OperatorModeCode,
    OperatorModeState, ProcessRunState,
};
use harvest_ipc::period_stats::PeriodStatsError;
use harvest_ipc::{Context, Domain, FixedString, Flow, HealthReporter, MonotonicClock, Publisher};
use harvest_operator::mode_file::{load_mode, mode_path, save_mode};
use harvest_operator::token::{CONTROL_TOKEN_ENV, TokenError, read_token_file, token_path};
use harvest_operator::{
    Action, ArmView, ControlToken, Decision, Executive, ExecutiveConfig, PlatformView, Refusal,
    StackView,
};

/// The mode the executive starts in (when no earlier mode of this run is known).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum InitialMode {
    /// Nothing moves until the operator starts the harvest (the robot's default).
    Idle,
    /// Harvest at once (the simulated robot's launch profile).
    Harvesting,
}

/// Which platform device the executive drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PlatformDevice {
    /// The simulated platform behind `hw/platform/command|feedback`.
    Sim,
    /// No platform: platform commands are refused.
    None,
}

/// `harvest executive` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct ExecutiveArgs {
    /// Mode at start.
    #[arg(long, value_enum, default_value = "idle")]
    pub initial_mode: InitialMode,
    /// Platform device.
    #[arg(long, value_enum, default_value = "sim")]
    pub platform: PlatformDevice,
    /// Control period, us (default 5000: 200 Hz, the arms' rate).
    #[arg(long, default_value_t = 5000, value_parser = clap::value_parser!(u64).range(500..=100_000))]
    pub control_period_us: u64,
    /// Token file read when `$HARVEST_CONTROL_TOKEN` is not set (default: the domain's, see
    /// `harvest_operator::token::token_path`).
    #[arg(long)]
    pub token_file: Option<PathBuf>,
    /// Work a row stop by stop: this many stops (0: no row, the robot stays where
    /// it is). Needs the simulated tractor (`harvest sim --row`).
    #[arg(long, default_value_t = 0)]
    pub row_stops: u32,
    /// Distance between two stops along the row, m.
    #[arg(long, default_value_t = 2.0)]
    pub stop_spacing_m: f64,
    /// Advance to the next stop once a stop is harvested (without it, the operator ends each
    /// stop: `harvest ctl next-stop`).
    #[arg(long)]
    pub auto_advance: bool,
    /// A stop is harvested once the arms are parked and nothing was assigned or attempted for
    /// this long after fresh detections (or when the vacuum supervisor reports it complete), ms.
    #[arg(long, default_value_t = 4000)]
    pub stop_quiet_ms: u64,
}

/// Why the executive stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ExecutiveProcessError {
    /// No control token.
    #[error("control token: {0} (or set ${CONTROL_TOKEN_ENV})")]
    Token(#[from] TokenError),
    /// The period statistics could not be set up.
    #[error(transparent)]
    Period(#[from] PeriodStatsError),
    /// The platform could not be reached.
    #[error("platform device: {0}")]
    Platform(#[source] AnyDeviceError),
    /// The row's stop-and-go cycle refused its settings.
    #[error("row: {0}")]
    Row(#[from] StopCycleError),
    /// The tractor could not be reached.
    #[error("row: tractor device: {0}")]
    Tractor(#[source] AnyDeviceError),
    /// The transport failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(ExecutiveProcessError);

/// `operator/mode` is re-sent this often, ns.
const MODE_PERIOD_NS: u64 = 100_000_000;
/// The platform is polled this often, ns.
const PLATFORM_PERIOD_NS: u64 = 100_000_000;
/// The platform driver waits this long for its first feedback, and refuses older feedback.
const PLATFORM_TIMEOUT: Duration = Duration::from_millis(100);
/// How long the start waits for both arms' states, ns.
const START_WAIT_NS: u64 = 200_000_000;

/// The platform behind its trait, or none.
enum PlatformLink {
    Sim(Box<SimPlatform>),
    None,
}

/// Why a platform action or poll did not happen.
#[derive(Debug, thiserror::Error)]
enum PlatformFailure {
    /// The stack runs without a platform.
    #[error("{}", Refusal::NoPlatform)]
    Absent,
    /// The platform's driver failed or refused; the source keeps its kind.
    #[error(transparent)]
    Device(AnyDeviceError),
}

impl PlatformFailure {
    /// The device error's kind for the heartbeat (`None` without a device error).
    fn device_error(&self) -> DeviceErrorCode {
        match self {
            Self::Absent => DeviceErrorCode::None,
            Self::Device(error) => error.kind().into(),
        }
    }
}

impl PlatformLink {
    fn poll(&mut self) -> Result<Option<PlatformView>, PlatformFailure> {
        let (position, travel) = match self {
            Self::Sim(platform) => (
                platform
                    .position()
                    .map_err(|e| PlatformFailure::Device(AnyDeviceError::new(e)))?,
                platform.travel(),
            ),
            Self::None => return Ok(None),
        };
        Ok(Some(PlatformView {
            position_m: [position.in_out_m, position.up_down_m],
            in_motion: position.in_motion,
            travel_max_m: [travel.in_out_max_m, travel.up_down_max_m],
        }))
    }

    fn move_to(&mut self, target_m: [f64; 2]) -> Result<(), PlatformFailure> {
        match self {
            Self::Sim(platform) => platform
                .move_to(target_m[0], target_m[1])
                .map_err(|e| PlatformFailure::Device(AnyDeviceError::new(e))),
            Self::None => Err(PlatformFailure::Absent),
        }
    }

    fn stop(&mut self) -> Result<(), PlatformFailure> {
        match self {
            Self::Sim(platform) => platform
                .stop()
                .map_err(|e| PlatformFailure::Device(AnyDeviceError::new(e))),
            Self::None => Ok(()),
        }
    }

    fn present(&self) -> bool {
        matches!(self, Self::Sim(_))
    }
}

/// The control token: the environment's, else the token file's.
fn control_token(
    args: &ExecutiveArgs,
    domain: &Domain,
) -> Result<(ControlToken, PathBuf), TokenError> {
    let path = args
        .token_file
        .clone()
        .unwrap_or_else(|| token_path(domain.name()));
    match std::env::var(CONTROL_TOKEN_ENV) {
        Ok(text) if !text.is_empty() => Ok((ControlToken::parse(&text, CONTROL_TOKEN_ENV)?, path)),
        _ => Ok((read_token_file(&path)?, path)),
    }
}

/// Runs the executive until SIGINT/SIGTERM.
pub fn run(
    args: &ExecutiveArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<(), ExecutiveProcessError> {
    let (token, token_file) = control_token(args, domain)?;
    let mode_file = mode_path(&token_file);
    let context = Context::new(domain, process_name)?;
    let mut platform = match args.platform {
        PlatformDevice::Sim => PlatformLink::Sim(Box::new(
            SimPlatform::connect(&context, PlatformTravel::default(), PLATFORM_TIMEOUT)
                .map_err(|error| ExecutiveProcessError::Platform(AnyDeviceError::new(error)))?,
        )),
        PlatformDevice::None => PlatformLink::None,
    };
    let mut row = if args.row_stops > 0 {
        let travel = PlatformTravel::default();
        Some(RowLink::connect(
            &context,
            RowOptions {
                stops: args.row_stops,
                stop_spacing_m: args.stop_spacing_m,
                auto_advance: args.auto_advance,
                quiet_ms: args.stop_quiet_ms,
            },
            [travel.in_out_max_m, travel.up_down_max_m],
        )?)
    } else {
        None
    };
    let commands_in = context.subscriber_with_buffer(OPERATOR_COMMAND, 256)?;
    let violations_in = context.subscriber_with_buffer(SAFETY_VIOLATION, 256)?;
    let arm_states_in = [
        context.subscriber(ARM_STATE[0])?,
        context.subscriber(ARM_STATE[1])?,
    ];
    let estop_in = context.subscriber(EMERGENCY_STOP)?;
    let mut estop_out = context.publisher(EMERGENCY_STOP)?;
    let mut ack_out = context.publisher(OPERATOR_ACK)?;
    let mut mode_out = context.publisher(OPERATOR_MODE)?;
    let mut manual_out = [
        context.publisher(ARM_MANUAL[0])?,
        context.publisher(ARM_MANUAL[1])?,
    ];
    let mut health = HealthReporter::new(&context)?;

    let config = ExecutiveConfig {
        initial_mode: match args.initial_mode {
            InitialMode::Idle => OperatorModeCode::Idle,
            InitialMode::Harvesting => OperatorModeCode::Harvesting,
        },
        field_row: row.is_some(),
        ..ExecutiveConfig::default()
    };
    let started_ns = MonotonicClock::read_ns();
    let mut executive: Option<Executive> = None;
    let mut arm_states: [Option<ArmState>; 2] = [None; 2];
    let mut estop_seen = false;
    let mut view = StackView::default();
    let mut last_platform_poll_ns = 0u64;
    let mut platform_failures = 0u32;
    let mut last_mode_ns = 0u64;
    let mut published: Option<(u8, [bool; 2], u64, u64, bool)> = None;
    let mut handled = 0u64;
    tracing::info!(period_us = args.control_period_us, platform = ?args.platform,
        initial_mode = ?args.initial_mode, "executive running");

    run_control_loop(
        args.control_period_us * 1000,
        |wake| -> Result<Flow, ExecutiveProcessError> {
            match wake {
                Wake::Tick { now_ns } => {
                    // 1. The stack.
                    for (i, subscriber) in arm_states_in.iter().enumerate() {
                        if let Some(state) = subscriber.receive_latest()? {
                            arm_states[i] = Some(*state);
                        }
                    }
                    if let Some(sample) = estop_in.receive_latest()? {
                        estop_seen |= sample.engaged != 0;
                    }
                    view.arms = arm_states.map(|s| s.map(|s| ArmView::from_state(&s, now_ns)));
                    let poll_every_ns = if platform_failures >= 3 {
                        10 * PLATFORM_PERIOD_NS
                    } else {
                        PLATFORM_PERIOD_NS
                    };
                    if platform.present()
                        && now_ns.saturating_sub(last_platform_poll_ns) >= poll_every_ns
                    {
                        last_platform_poll_ns = now_ns;
                        match platform.poll() {
                            Ok(platform_view) => {
                                platform_failures = 0;
                                view.platform = platform_view;
                            }
                            Err(error) => {
                                health.note_device_error(error.device_error());
                                platform_failures = platform_failures.saturating_add(1);
                                if platform_failures == 3 {
                                    tracing::warn!(%error, "platform silent: polling at 1 Hz");
                                }
                                view.platform = None;
                            }
                        }
                    }

                    // The executive, once the arms have spoken (or the start wait is over).
                    if executive.is_none() {
                        let both = arm_states.iter().all(Option::is_some);
                        if !both && now_ns.saturating_sub(started_ns) < START_WAIT_NS {
                            return Ok(Flow::Continue);
                        }
                        let arm_stopped = arm_states
                            .iter()
                            .flatten()
                            .any(|s| s.phase == ArmPhase::Stopped);
                        let engaged = estop_seen || arm_stopped;
                        let previous =
                            load_mode(&mode_file, &token).map(|(mode, arms)| OperatorModeState {
                                mode: mode as u8,
                                arms_enabled: arms.map(u8::from),
                                ..OperatorModeState::default()
                            });
                        let new = Executive::new(
                            config,
                            token.clone(),
                            now_ns,
                            engaged,
                            previous.as_ref(),
                        );
                        if engaged {
                            publish_estop(
                                &mut estop_out,
                                now_ns,
                                true,
                                "engaged before the executive started",
                            )?;
                        }
                        executive = Some(new);
                    }
                    let Some(executive) = executive.as_mut() else {
                        return Ok(Flow::Continue);
                    };

                    // 2. The safety monitor's stop requests, then the operator's commands.
                    while let Some(violation) = violations_in.receive()? {
                        if !violation.requests_stop() {
                            continue;
                        }
                        let text = violation.description.as_str().to_owned();
                        for action in executive.protective_stop(now_ns, &text) {
                            if let Err(failure) = apply(
                                &action,
                                now_ns,
                                &mut estop_out,
                                &mut manual_out,
                                &mut platform,
                            )? {
                                health.note_device_error(failure.device_error());
                                tracing::warn!(%failure, ?action, "action failed");
                            }
                        }
                    }
                    while let Some(command) = commands_in.receive()? {
                        handled += 1;
                        let mut decision = executive.handle(now_ns, &command, &view);
                        let actions = std::mem::take(&mut decision.actions);
                        for action in &actions {
                            if *action == Action::NextStop {
                                // The row's stop cycle has the last word.
                                let platform_now =
                                    view.platform.map(|p| (p.position_m, p.in_motion));
                                let outcome = match row.as_mut() {
                                    Some(row) => {
                                        row.next_stop(now_ns, &arm_states, platform_now)?
                                    }
                                    None => Err(Refusal::NoRow.to_string()),
                                };
                                match outcome {
                                    Ok((what, target_m)) => {
                                        decision.reason = what;
                                        if let Some(target_m) = target_m
                                            && let Err(failure) = platform.move_to(target_m)
                                        {
                                            health.note_device_error(failure.device_error());
                                            tracing::warn!(%failure, ?target_m, "platform move refused");
                                        }
                                    }
                                    Err(reason) => decision.refuse(Refusal::NextStop(reason)),
                                }
                                continue;
                            }
                            if let Err(failure) = apply(
                                action,
                                now_ns,
                                &mut estop_out,
                                &mut manual_out,
                                &mut platform,
                            )? {
                                health.note_device_error(failure.device_error());
                                tracing::warn!(%failure, ?action, "action failed");
                                if decision.is_accepted() {
                                    decision.refusal = Some(Refusal::NoPlatform);
                                    decision.reason = failure.to_string();
                                }
                            }
                        }
                        publish_ack(&mut ack_out, now_ns, &command, &decision, executive.mode())?;
                    }

                    // 3. Silent sessions.
                    for action in executive.tick(now_ns, &view) {
                        if let Err(message) = apply(
                            &action,
                            now_ns,
                            &mut estop_out,
                            &mut manual_out,
                            &mut platform,
                        )? {
                            tracing::warn!(%message, ?action, "action failed");
                        }
                    }

                    // 3b. The row's stop-and-go cycle (only while harvesting).
                    if let Some(row) = row.as_mut() {
                        let harvesting = executive.mode() == OperatorModeCode::Harvesting;
                        let platform_now = view.platform.map(|p| (p.position_m, p.in_motion));
                        if let Some(target_m) =
                            row.tick(now_ns, harvesting, &arm_states, platform_now)?
                        {
                            match platform.move_to(target_m) {
                                Ok(()) => {
                                    // Poll at once: the stop cycle waits for the move to end.
                                    last_platform_poll_ns = 0;
                                    view.platform = None;
                                }
                                Err(message) => {
                                    tracing::warn!(%message, ?target_m, "platform move refused")
                                }
                            }
                        }
                    }

                    // 4. The mode.
                    let field_hold = row.as_ref().is_some_and(RowLink::holds_approaches);
                    let change = executive.last_change();
                    let key = (
                        executive.mode() as u8,
                        executive.arms_enabled(),
                        change.at_ns,
                        executive.controller().map_or(0, |c| c.session_id),
                        field_hold,
                    );
                    let changed = published != Some(key);
                    if changed || now_ns.saturating_sub(last_mode_ns) >= MODE_PERIOD_NS {
                        mode_out.publish_with(now_ns, |state| {
                            executive.fill_state(state);
                            state.platform_present = u8::from(platform.present());
                            state.field_hold = u8::from(field_hold);
                            match view.platform {
                                Some(p) => {
                                    state.platform_in_motion = u8::from(p.in_motion);
                                    state.platform_position_m = p.position_m;
                                }
                                None => {
                                    state.platform_in_motion = 0;
                                    state.platform_position_m = [f64::NAN; 2];
                                }
                            }
                        })?;
                        last_mode_ns = now_ns;
                        if changed
                            && published.is_none_or(|p| (p.0, p.1) != (key.0, key.1))
                            && let Err(error) = save_mode(
                                &mode_file,
                                &token,
                                executive.mode(),
                                executive.arms_enabled(),
                            )
                        {
                            tracing::warn!(%error, path = %mode_file.display(), "mode file not written");
                        }
                        published = Some(key);
                    }
                }
                Wake::Heartbeat { period } => {
                    let mode = executive.as_ref().map_or(0, |e| e.mode() as u64);
                    let _ = period;
                    health.report(ProcessRunState::Running, handled, "mode", mode)?;
                }
            }
            Ok(Flow::Continue)
        },
    )?;
    tracing::info!(commands = handled, "executive stopped");
    Ok(())
}

/// Carries out one action; `Ok(Err(failure))` when the platform is absent or its device failed
/// or refused.
fn apply(
    action: &Action,
    now_ns: u64,
    estop_out: &mut Publisher<harvest_ipc::payloads::EmergencyStop>,
    manual_out: &mut [Publisher<harvest_ipc::payloads::ArmManualCommand>; 2],
    platform: &mut PlatformLink,
) -> Result<Result<(), PlatformFailure>, ExecutiveProcessError> {
    match action {
        Action::EngageEmergencyStop { reason } => publish_estop(estop_out, now_ns, true, reason)?,
        Action::ReleaseEmergencyStop => {
            publish_estop(estop_out, now_ns, false, "released by the operator")?;
        }
        Action::ArmMoveTo {
            arm,
            goal,
            speed_fraction,
            request_id,
        } => {
            manual_out[usize::from(arm - 1)].publish_with(now_ns, |order| {
                order.request_id = *request_id;
                order.arm_id = *arm;
                order.kind = ArmManualKind::MoveTo as u8;
                order._reserved = [0; 6];
                order.goal_joint_position = *goal;
                order.speed_fraction = *speed_fraction;
            })?;
        }
        Action::ArmStop { arm } => {
            manual_out[usize::from(arm - 1)].publish_with(now_ns, |order| {
                order.request_id = 0;
                order.arm_id = *arm;
                order.kind = ArmManualKind::Stop as u8;
                order._reserved = [0; 6];
                order.goal_joint_position = [f64::NAN; 4];
                order.speed_fraction = 0.0;
            })?;
        }
        Action::PlatformMoveTo { target_m } => return Ok(platform.move_to(*target_m)),
        Action::PlatformStop => return Ok(platform.stop()),
        // Carried out by the row's stop cycle in the command loop of `run`.
        Action::NextStop => {}
    }
    Ok(Ok(()))
}

fn publish_estop(
    estop_out: &mut Publisher<harvest_ipc::payloads::EmergencyStop>,
    now_ns: u64,
    engaged: bool,
    reason: &str,
) -> Result<(), ExecutiveProcessError> {
    if engaged {
        tracing::warn!(%reason, "emergency stop engaged");
    } else {
        tracing::info!(%reason, "emergency stop released");
    }
    estop_out.publish_with(now_ns, |stop| {
        stop.engaged = u8::from(engaged);
        stop._reserved = [0; 7];
        stop.reason = FixedString::new(reason);
    })?;
    Ok(())
}

fn publish_ack(
    ack_out: &mut Publisher<harvest_ipc::payloads::OperatorAck>,
    now_ns: u64,
    command: &OperatorCommand,
    decision: &Decision,
    mode: OperatorModeCode,
) -> Result<(), ExecutiveProcessError> {
    ack_out.publish_with(now_ns, |ack| {
        ack.request_id = command.request_id;
        ack.session_id = command.session_id;
        ack.code = command.code;
        ack.accepted = u8::from(decision.is_accepted());
        ack.refusal = decision.refusal.as_ref().map_or(0, |r| r.code() as u8);
        ack.mode = mode as u8;
        ack._reserved = [0; 3];
        ack.motion_duration_ms = decision.motion_duration_ms;
        ack._reserved2 = [0; 4];
        ack.reason = FixedString::new(&decision.reason);
    })?;
    Ok(())
}
