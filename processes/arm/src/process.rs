//! `harvest arm --id 1|2`: one arm's 200 Hz control loop over the channels.
//!
//! Per tick (a wait-set interval of [`ArmProcessConfig::control_period_us`], never a sleep), in
//! the order of the in-process evaluation (`harvest_eval::harvest::runner`, steps 2, 3 and 5):
//! 1. the encoders are read through the [`ArmServos`] trait;
//! 2. the newest samples of this arm's target, `vacuum/state`, this arm's `vacuum/valve_grant`
//!    answers, the other arm's state and target, and `safety/emergency_stop` are taken;
//! 3. [`ArmNode::step`] runs;
//! 4. its servo order goes to the servos through the trait (`command` or `hold`; a set-point
//!    the driver refuses brakes the arm instead);
//! 5. `armN/command` (the set-points, the current apple and the capture time of the detection
//!    behind its target), `armN/state`, `vacuum/valve_request` (on change, and re-sent every
//!    [`ArmProcessConfig::valve_request_resend_ms`] so a restarted vacuum supervisor learns the
//!    standing request) and the node's events on `harvest/events` are published.
//!
//! The operator (`operator/mode`, from `harvest executive`): while the mode is not harvesting,
//! or this arm is disabled, new targets are held back (an attempt under way runs to its end).
//! Manual orders on `armN/manual` are carried out only in manual mode; a manual move stops as
//! soon as the mode leaves manual or is not heard for [`MODE_STALE_NS`] (the executive is
//! gone). With no mode ever published (a stack without the executive) the arm harvests as
//! before.
//!
//! Until the servos report encoder feedback for the first time the arm is not ready: nothing
//! is stepped or published.
//!
//! The loop measures its own tick-to-tick intervals ([`run_control_loop`]): the p99 goes out
//! with every heartbeat (`period_p99_us`), the full distribution is logged at shutdown. On
//! SIGTERM the arm brakes and asks for its valve to be closed before exiting.
//!
//! The device implementation is chosen in one place, [`run`] (`--device sim`: the simulated
//! servos behind `hw/armN/servo|encoders`), together with its timing profile
//! ([`ArmDevice::node_config`]).

use std::path::{Path, PathBuf};

use harvest_hw::arm_servos::ArmServos;
use harvest_hw::arm_servos::sim::SimArmServos;
use harvest_hw::{AnyDeviceError, DeviceError};
use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_MANUAL, ARM_STATE, ARM_TARGET, EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_MODE,
    VACUUM_STATE, VALVE_GRANT, VALVE_REQUEST,
};
use harvest_ipc::config_file::{ConfigFileError, read_toml};
use harvest_ipc::payloads::{
    ArmPhase as PhaseCode, ArmState, ArmTarget, HarvestEventKind, VacuumState, ValveGrant,
    ValveRequest,
};
use harvest_ipc::{Context, Domain, Flow, HealthReporter, MonotonicClock};
use serde::Deserialize;

use harvest_arm::harvest_events::ArmEventReporter;
use harvest_arm::node::{
    ArmNode, ArmNodeConfig, ArmNodeError, ArmNodeInput, EncoderSample, OtherArmInput, ServoOrder,
};
use harvest_ipc::control_loop::{Wake, run_control_loop};
use harvest_ipc::failure_streak::FailureStreak;
use harvest_ipc::period_stats::{PeriodStatsError, PeriodSummary};
use harvest_robot_model::params::{ArmId, ArmParams};

/// Which servo device drives the arm (the one place the implementation is chosen).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ArmDevice {
    /// The simulated servos behind `hw/armN/servo` and `hw/armN/encoders`.
    Sim,
}

/// Attach timeout of the arm with the simulated valve box, s: the vacuum supervisor's 0.5 s
/// (`harvest_vacuum::process::SIM_ATTACH_TIMEOUT_NS`, the scenario's tube lag) plus 50 ms, so
/// the arm gives up just after the supervisor declared the failure (eq. 8, third clause). This
/// follows the simulated vacuum plant (its tube and source lags), not the simulator's timing:
/// it goes when the vacuum supervisor's simulated attach timeout goes.
pub const SIM_ATTACH_TIMEOUT_S: f64 = 0.55;

impl ArmDevice {
    /// The node settings that fit this device. The simulator serves encoder feedback at its
    /// 200 Hz servo rate whatever it renders (its physics runs on a thread of its own), so the
    /// feedback checks are the robot's ([`ArmNodeConfig::default`]); only the attach timeout
    /// follows the simulated vacuum plant ([`SIM_ATTACH_TIMEOUT_S`]).
    pub fn node_config(self) -> ArmNodeConfig {
        match self {
            Self::Sim => {
                let mut config = ArmNodeConfig::default();
                config.cycle.attach_timeout_s = SIM_ATTACH_TIMEOUT_S;
                config
            }
        }
    }
}

/// `harvest arm` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct ArmArgs {
    /// Which arm: 1 (left, +y) or 2 (right, -y).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub id: u8,
    /// Servo device.
    #[arg(long, value_enum, default_value = "sim")]
    pub device: ArmDevice,
    /// Process settings (TOML file, every key optional; see `ArmProcessConfig`).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Settings of the arm process (`--config FILE`). Every key is optional.
///
/// ```toml
/// control_period_us = 5000          # 200 Hz
/// valve_request_resend_ms = 500
/// # [node] ... a complete ArmNodeConfig (with [node.cycle] and [node.cycle.gains]);
/// # default: the device's profile (ArmDevice::node_config)
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ArmProcessConfig {
    /// Control period, us (default 5000: 200 Hz, paper 003 section 2.2).
    pub control_period_us: u64,
    /// The standing valve request is re-sent this often, ms (default 500).
    pub valve_request_resend_ms: u64,
    /// Node settings; `None`: the device's profile.
    pub node: Option<ArmNodeConfig>,
}

impl Default for ArmProcessConfig {
    fn default() -> Self {
        Self {
            control_period_us: 5000,
            valve_request_resend_ms: 500,
            node: None,
        }
    }
}

impl ArmProcessConfig {
    /// Reads and checks a settings file.
    pub fn from_path(path: &Path) -> Result<Self, ArmProcessError> {
        let config: Self = read_toml(path, "arm settings")?;
        config.validate()?;
        Ok(config)
    }

    fn validate(&self) -> Result<(), ArmProcessError> {
        if !(500..=100_000).contains(&self.control_period_us) {
            return Err(ArmProcessError::InvalidConfig {
                key: "control_period_us",
                value: self.control_period_us,
                expected: "500..=100000 (2 kHz to 10 Hz)",
            });
        }
        if self.valve_request_resend_ms == 0 {
            return Err(ArmProcessError::InvalidConfig {
                key: "valve_request_resend_ms",
                value: 0,
                expected: "> 0",
            });
        }
        Ok(())
    }
}

/// Why the arm process stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ArmProcessError {
    /// The settings file could not be read.
    #[error(transparent)]
    Config(#[from] ConfigFileError),
    /// A setting is out of range.
    #[error("arm settings: `{key}` = {value}: expected {expected}")]
    InvalidConfig {
        key: &'static str,
        value: u64,
        expected: &'static str,
    },
    /// The node refused its settings.
    #[error(transparent)]
    Node(#[from] ArmNodeError),
    /// The period statistics could not be set up.
    #[error(transparent)]
    Period(#[from] PeriodStatsError),
    /// The servo device could not be reached, or failed too many times in a row.
    #[error("arm {arm} servo device: {source}")]
    Device {
        /// The arm, 1 or 2.
        arm: u8,
        /// The driver's error, with its kind.
        source: AnyDeviceError,
    },
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(ArmProcessError);

/// A manual move stops when `operator/mode` was not heard for this long (the executive
/// re-sends it at 10 Hz), ns.
pub const MODE_STALE_NS: u64 = 500_000_000;

/// Device errors in a row after which the process stops (and the supervisor restarts it).
const MAX_CONSECUTIVE_DEVICE_ERRORS: u32 = 200;

/// Runs arm `args.id` until SIGINT/SIGTERM; returns its control period statistics.
pub fn run(
    args: &ArmArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<PeriodSummary, ArmProcessError> {
    let config = match &args.config {
        Some(path) => ArmProcessConfig::from_path(path)?,
        None => ArmProcessConfig::default(),
    };
    let arm = match args.id {
        1 => ArmId::Arm1,
        _ => ArmId::Arm2,
    };
    let node_config = config.node.unwrap_or_else(|| args.device.node_config());
    let context = Context::new(domain, process_name)?;
    let params = ArmParams::for_arm(arm);
    let lo = params.position_limits.min.to_array();
    let hi = params.position_limits.max.to_array();
    let limits = std::array::from_fn(|j| [lo[j], hi[j]]);
    let device_error = |source: AnyDeviceError| ArmProcessError::Device {
        arm: arm.number(),
        source,
    };
    match args.device {
        ArmDevice::Sim => {
            let servos = SimArmServos::connect(&context, arm, limits)
                .map_err(|error| device_error(AnyDeviceError::new(error)))?;
            control_loop(&context, servos, arm, &config, node_config)
        }
    }
}

/// The newest sample of every input channel the node reads.
#[derive(Debug, Default)]
struct Inputs {
    target: Option<ArmTarget>,
    vacuum: Option<VacuumState>,
    grant: Option<ValveGrant>,
    other_state: Option<ArmState>,
    other_target: Option<ArmTarget>,
    emergency_stop: bool,
}

fn control_loop<S: ArmServos>(
    context: &Context,
    mut servos: S,
    arm: ArmId,
    config: &ArmProcessConfig,
    node_config: ArmNodeConfig,
) -> Result<PeriodSummary, ArmProcessError> {
    let i = arm.index();
    let other = 1 - i;
    let number = arm.number();
    let mut node = ArmNode::new(arm, node_config)?;
    let mut reporter = ArmEventReporter::new(arm);

    let target_in = context.subscriber(ARM_TARGET[i])?;
    let vacuum_in = context.subscriber(VACUUM_STATE)?;
    let grant_in = context.subscriber(VALVE_GRANT)?;
    let other_state_in = context.subscriber(ARM_STATE[other])?;
    let other_target_in = context.subscriber(ARM_TARGET[other])?;
    let estop_in = context.subscriber(EMERGENCY_STOP)?;
    let mode_in = context.subscriber(OPERATOR_MODE)?;
    let manual_in = context.subscriber(ARM_MANUAL[i])?;
    let mut operator_mode: Option<harvest_ipc::payloads::OperatorModeState> = None;
    let mut command_out = context.publisher(ARM_COMMAND[i])?;
    let mut state_out = context.publisher(ARM_STATE[i])?;
    let mut request_out = context.publisher(VALVE_REQUEST)?;
    let mut events_out = context.publisher(HARVEST_EVENTS)?;
    let mut health = HealthReporter::new(context)?;

    let period_ns = config.control_period_us * 1000;
    let resend_ns = config.valve_request_resend_ms * 1_000_000;

    let mut inputs = Inputs::default();
    let mut last_request: Option<(ValveRequest, u64)> = None;
    let mut device_errors = FailureStreak::new(MAX_CONSECUTIVE_DEVICE_ERRORS);
    let mut ticks = 0u64;
    tracing::info!(arm = %arm, period_us = config.control_period_us, "arm control loop running");
    let summary = run_control_loop(period_ns, |wake| -> Result<Flow, ArmProcessError> {
        match wake {
            Wake::Tick { now_ns } => {
                ticks += 1;

                // 1. Encoders.
                let feedback = match servos.feedback() {
                    Ok(sample) => {
                        device_errors.succeeded();
                        sample.map(|f| EncoderSample {
                            capture_ns: f.capture_ns,
                            position: f.position,
                            velocity: f.velocity,
                        })
                    }
                    Err(error) => {
                        health.note_device_error(error.kind().into());
                        if device_errors.failed("encoder read", &error).is_some() {
                            return Err(ArmProcessError::Device {
                                arm: number,
                                source: AnyDeviceError::new(error),
                            });
                        }
                        None
                    }
                };

                // Until the servos report for the first time the arm is not ready: nothing is
                // stepped or published (no state: the vacuum supervisor assigns it nothing and
                // the other arm defers its motions).
                if feedback.is_none() {
                    return Ok(Flow::Continue);
                }

                // 2. Channels.
                read_inputs(
                    number,
                    &mut inputs,
                    &target_in,
                    &vacuum_in,
                    &grant_in,
                    &other_state_in,
                    &other_target_in,
                    &estop_in,
                )?;

                // The operator's mode and manual orders.
                if let Some(sample) = mode_in.receive_latest()? {
                    operator_mode = Some(*sample);
                }
                obey_operator(
                    &mut node,
                    number,
                    now_ns,
                    operator_mode.as_ref(),
                    &manual_in,
                )?;

                // 3. The node.
                let input = ArmNodeInput {
                    now_ns,
                    feedback,
                    target: inputs.target.as_ref(),
                    vacuum: inputs.vacuum.as_ref(),
                    grant: inputs.grant.as_ref(),
                    other_arm: inputs.other_state.as_ref().map(|state| OtherArmInput {
                        state,
                        target: inputs.other_target.as_ref(),
                    }),
                    emergency_stop: inputs.emergency_stop,
                };
                let out = node.step(&input);

                // 4. Servos.
                let hold = match out.servo {
                    ServoOrder::Track { position, velocity } => {
                        match servos.command(position, velocity) {
                            Ok(()) => false,
                            Err(error) => {
                                tracing::warn!(%error, ?position, "set-point refused: braking");
                                health.note_device_error(error.kind().into());
                                if let Err(error) = servos.hold() {
                                    tracing::warn!(%error, "brake command failed");
                                }
                                true
                            }
                        }
                    }
                    ServoOrder::Hold => {
                        if let Err(error) = servos.hold() {
                            tracing::warn!(%error, "brake command failed");
                        }
                        true
                    }
                };

                // 5. Outputs.
                // The node's own state: its phase code is always known.
                let phase = out.state.phase.get().unwrap_or(PhaseCode::Idle);
                for event in &out.events {
                    if let Some(harvest_event) =
                        reporter.convert(now_ns, phase, event, inputs.target.as_ref())
                    {
                        if harvest_event.kind == HarvestEventKind::TargetRejected {
                            tracing::info!(apple_id = harvest_event.apple_id,
                                reason = %harvest_event.reason, "target rejected");
                        }
                        events_out.publish(&harvest_event)?;
                    }
                }
                reporter.end_tick();
                let (apple_id, source_capture_ns) = reporter
                    .current_target()
                    .map_or((0, 0), |t| (t.apple_id, t.source_capture_ns));
                let (position, velocity) = match out.servo {
                    ServoOrder::Track { position, velocity } if !hold => (position, velocity),
                    _ => (out.state.joint_position, [0.0; 4]),
                };
                command_out.publish_with(now_ns, |command| {
                    command.arm_id = number;
                    command.hold = u8::from(hold);
                    command._reserved = [0; 2];
                    command.apple_id = apple_id;
                    command.source_capture_ns = source_capture_ns;
                    command.joint_position = position;
                    command.joint_velocity = velocity;
                })?;
                state_out.publish(&out.state)?;
                let request = out.valve_request;
                let due = match last_request {
                    None => true,
                    Some((last, at_ns)) => {
                        last.request_seq != request.request_seq
                            || last.kind != request.kind
                            || now_ns.saturating_sub(at_ns) >= resend_ns
                    }
                };
                if due {
                    let mut message = request;
                    message.header.capture_ns = now_ns;
                    request_out.publish(&message)?;
                    last_request = Some((request, now_ns));
                }
            }
            Wake::Heartbeat { period } => {
                let state = device_errors.run_state();
                health.report_control_loop(state, ticks, &period)?;
            }
        }
        Ok(Flow::Continue)
    })?;

    // Leave the arm braked with its valve closed.
    if let Err(error) = servos.hold() {
        tracing::warn!(%error, "final brake command failed");
    }
    let close = ValveRequest {
        header: harvest_ipc::Header {
            capture_ns: MonotonicClock::read_ns(),
            ..harvest_ipc::Header::default()
        },
        arm_id: number,
        kind: harvest_ipc::payloads::ValveRequestKind::Close.into(),
        _reserved: [0; 2],
        request_seq: last_request.map_or(0, |(r, _)| r.request_seq.wrapping_add(1)),
    };
    request_out.publish(&close)?;
    tracing::info!(
        arm = %arm,
        harvested = node.harvested_count(),
        device_errors = device_errors.total(),
        p50_us = summary.p50_ns / 1000,
        p99_us = summary.p99_ns / 1000,
        max_us = summary.max_ns / 1000,
        "arm stopped; control period: {summary}"
    );
    Ok(summary)
}

/// Holds new targets unless harvesting with this arm enabled, and carries out manual orders
/// in manual mode only (module docs).
fn obey_operator(
    node: &mut ArmNode,
    number: u8,
    now_ns: u64,
    mode: Option<&harvest_ipc::payloads::OperatorModeState>,
    manual_in: &harvest_ipc::Subscriber<harvest_ipc::payloads::ArmManualCommand>,
) -> Result<(), ArmProcessError> {
    use harvest_ipc::payloads::{ArmManualKind, OperatorModeCode};
    let code = mode.and_then(|m| m.mode_code());
    let enabled = mode.is_none_or(|m| m.arms_enabled[usize::from(number - 1)] != 0);
    let harvesting = mode.is_none() || code == Some(OperatorModeCode::Harvesting);
    node.hold_targets(!(harvesting && enabled));
    let manual_fresh = code == Some(OperatorModeCode::Manual)
        && mode.is_some_and(|m| now_ns.saturating_sub(m.header.capture_ns) <= MODE_STALE_NS);
    while let Some(order) = manual_in.receive()? {
        if order.arm_id != number {
            continue;
        }
        match order.manual_kind() {
            Some(ArmManualKind::MoveTo) if manual_fresh => {
                match node.start_manual(
                    now_ns,
                    order.goal_joint_position,
                    order.speed_fraction,
                    order.request_id,
                ) {
                    Ok(duration_s) => {
                        tracing::info!(request_id = order.request_id, duration_s, "manual move")
                    }
                    Err(refusal) => {
                        tracing::warn!(request_id = order.request_id, %refusal, "manual move refused")
                    }
                }
            }
            Some(ArmManualKind::MoveTo) => {
                tracing::warn!(request_id = order.request_id, mode = ?code,
                    "manual move refused: not in manual mode");
            }
            Some(ArmManualKind::Stop) => node.stop_manual(),
            None => tracing::warn!(kind = order.kind, "unknown manual order ignored"),
        }
    }
    if node.manual_active() && !manual_fresh {
        tracing::warn!(mode = ?code, "manual move stopped: mode left manual or went silent");
        node.stop_manual();
    }
    Ok(())
}

/// Takes the newest sample of each input channel (this arm's answers only on the shared grant
/// channel).
#[allow(clippy::too_many_arguments)]
fn read_inputs(
    number: u8,
    inputs: &mut Inputs,
    target_in: &harvest_ipc::Subscriber<ArmTarget>,
    vacuum_in: &harvest_ipc::Subscriber<VacuumState>,
    grant_in: &harvest_ipc::Subscriber<ValveGrant>,
    other_state_in: &harvest_ipc::Subscriber<ArmState>,
    other_target_in: &harvest_ipc::Subscriber<ArmTarget>,
    estop_in: &harvest_ipc::Subscriber<harvest_ipc::payloads::EmergencyStop>,
) -> Result<(), ArmProcessError> {
    if let Some(sample) = target_in.receive_latest()? {
        inputs.target = Some(*sample);
    }
    if let Some(sample) = vacuum_in.receive_latest()? {
        inputs.vacuum = Some(*sample);
    }
    while let Some(sample) = grant_in.receive()? {
        if sample.arm_id == number {
            inputs.grant = Some(*sample);
        }
    }
    if let Some(sample) = other_state_in.receive_latest()? {
        inputs.other_state = Some(*sample);
    }
    if let Some(sample) = other_target_in.receive_latest()? {
        inputs.other_target = Some(*sample);
    }
    if let Some(sample) = estop_in.receive_latest()? {
        inputs.emergency_stop = sample.engaged != 0;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_with_defaults_and_refuse_unknown_keys() {
        let config: ArmProcessConfig = toml::from_str("control_period_us = 2500").expect("parse");
        assert_eq!(config.control_period_us, 2500);
        assert_eq!(config.valve_request_resend_ms, 500);
        assert!(config.node.is_none());
        assert!(toml::from_str::<ArmProcessConfig>("control_period = 1").is_err());
        let bad = ArmProcessConfig {
            control_period_us: 0,
            ..ArmProcessConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(ArmProcessError::InvalidConfig {
                key: "control_period_us",
                ..
            })
        ));
    }

    #[test]
    fn the_sim_profile_gives_up_after_the_vacuum_supervisor() {
        let config = ArmDevice::Sim.node_config();
        assert_eq!(config.cycle.attach_timeout_s, SIM_ATTACH_TIMEOUT_S);
        assert!(ArmNode::new(ArmId::Arm1, config).is_ok());
    }

    #[test]
    fn the_sim_profile_checks_feedback_as_on_the_robot() {
        let sim = ArmDevice::Sim.node_config();
        let robot = ArmNodeConfig::default();
        assert_eq!(sim.cycle.max_feedback_age_s, robot.cycle.max_feedback_age_s);
        // Everything but the attach timeout is the robot's.
        let mut same = sim;
        same.cycle.attach_timeout_s = robot.cycle.attach_timeout_s;
        assert_eq!(same, robot);
    }
}
