//! `harvest vacuum`: the vacuum supervisor's 200 Hz loop over the channels: valves, pressure
//! inference, coordination policy and apple assignment ([`VacuumNode`]).
//!
//! Per tick (a wait-set interval of [`VacuumProcessConfig::control_period_us`], never a sleep),
//! in the order of the in-process evaluation (`harvest_eval::harvest::runner`, steps 2, 4, 5):
//! 1. the valve board is read through the [`ValveBoard`] trait (valve states and the three
//!    pressures);
//! 2. the newest detection set on `perception/apples`, both arms' states, their standing valve
//!    requests (`vacuum/valve_request`, newest per arm) and `safety/emergency_stop` are taken;
//! 3. [`VacuumNode::step`] runs, with the reachability of each apple by each arm from the arm
//!    kinematics ([`harvest_arm::node::pick_reachable`], the same test the evaluation uses);
//! 4. the valve commands go to the board (`close_all` on an emergency stop, `set_valve` for each
//!    valve whose commanded position changed);
//! 5. targets (`armN/target`), answers (`vacuum/valve_grant`), `vacuum/state` and the node's
//!    events (`harvest/events`) are published.
//!
//! When nothing is left to do for [`VacuumProcessConfig::complete_after_ms`] (nothing assigned,
//! dispatched or running, every taking-part arm idle, and the detection sets since the last
//! attempt brought nothing new to pick), a `HarvestComplete` event is published once; `harvest
//! up --until-harvested` stops the stack on it.
//!
//! The device is chosen in one place, [`run`] (`--device sim`: the simulated valve board behind
//! `hw/valves/command|readings`), together with the pressure thresholds calibrated for it
//! ([`VacuumDevice::pressure_config`]).

use std::path::{Path, PathBuf};
use std::time::Duration;

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_hw::valve_board::serial::{SerialBoardConfig, SerialValveBoard};
use harvest_hw::valve_board::sim::SimValveBoard;
use harvest_hw::valve_board::{ValveBoard, ValveId, ValveState};
use harvest_hw::{AnyDeviceError, DeviceError};
use harvest_ipc::catalogue::{
    ARM_STATE, ARM_TARGET, EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_MODE, PERCEPTION_APPLES,
    VACUUM_STATE, VALVE_GRANT, VALVE_REQUEST,
};
use harvest_ipc::config_file::{ConfigFileError, read_toml};
use harvest_ipc::control_loop::{Wake, run_control_loop};
use harvest_ipc::failure_streak::FailureStreak;
use harvest_ipc::payloads::{
    ArmPhase as PhaseCode, ArmState, HarvestEvent, HarvestEventKind, HarvestEventSource,
    ValveRequest,
};
use harvest_ipc::period_stats::{PeriodStatsError, PeriodSummary};
use harvest_ipc::{Context, Domain, FixedString, Flow, HealthReporter};
use serde::Deserialize;

use crate::policy_arg::PolicyArg;
use harvest_robot_model::ArmId;
use harvest_vacuum::harvest_events::{ArmContext, vacuum_event};
use harvest_vacuum::node::{
    BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeError, VacuumNodeEvent,
};
use harvest_vacuum::pressure::PressureConfig;

/// Which valve board the supervisor drives (the one place the implementation is chosen).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum VacuumDevice {
    /// The simulated valve board behind `hw/valves/command` and `hw/valves/readings`.
    Sim,
    /// The robot's Arduino valve board on a serial line (`--port`), through the documented line
    /// protocol (`harvest_hw::valve_board::protocol`).
    Serial,
}

/// Attach timeout with the simulated valve box, ns: with the scenario's 0.12 s tube lag and
/// 0.25 s source lag the arm vacuum needs up to about 0.4 s to cross the seal thresholds after
/// the other arm's failed attempt sagged the source (the evaluation's scenario timing profile,
/// `harvest_eval::harvest::timing`); the arm waits 50 ms longer
/// (`harvest_arm_process::process::SIM_ATTACH_TIMEOUT_S`).
pub const SIM_ATTACH_TIMEOUT_NS: u64 = 500_000_000;
impl VacuumDevice {
    /// The attachment inference thresholds for this device. The simulated valve box is the
    /// nominal valve line the default ratio thresholds are derived from
    /// (`harvest_vacuum::pressure`); only the attach timeout follows the simulated tube's lag.
    pub fn pressure_config(self) -> PressureConfig {
        match self {
            Self::Sim => PressureConfig {
                attach_timeout_ns: SIM_ATTACH_TIMEOUT_NS,
                ..PressureConfig::default()
            },
            Self::Serial => PressureConfig::default(),
        }
    }

    /// The arm settings of the same robot for the reachability test. Reachability depends on
    /// the geometry only (contact gap, stand-off, clearance), which the simulated robot shares
    /// with the real one; the arm process's device-specific timing does not enter it.
    pub fn arm_node_config(self) -> ArmNodeConfig {
        ArmNodeConfig::default()
    }
}

/// `harvest vacuum` command line.
#[derive(Debug, Clone, clap::Args)]
pub struct VacuumArgs {
    /// Coordination policy.
    #[arg(long, value_enum, default_value = "2024")]
    pub policy: PolicyArg,
    /// Arms that harvest: 1 (arm 1 alone) or 2.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub arms: u8,
    /// Valve board device.
    #[arg(long, value_enum, default_value = "sim")]
    pub device: VacuumDevice,
    /// Serial port of the valve board (with `--device serial`), e.g. `/dev/ttyACM0`.
    #[arg(long, required_if_eq("device", "serial"))]
    pub port: Option<String>,
    /// Process settings (TOML file, every key optional; see `VacuumProcessConfig`).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Settings of the vacuum process (`--config FILE`). Every key is optional.
///
/// ```toml
/// control_period_us = 5000      # 200 Hz
/// complete_after_ms = 2000
/// board_timeout_ms = 100
/// # [node] ... a complete VacuumNodeConfig (policy and arms come from the command line);
/// # default: defaults with the device's pressure thresholds.
/// # [arm_node] ... a complete ArmNodeConfig for the reachability test; default: the device's.
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VacuumProcessConfig {
    /// Control period, us (default 5000: 200 Hz, paper 003 section 2.2).
    pub control_period_us: u64,
    /// Nothing left to do for this long: the harvest is complete, ms (default 2000).
    pub complete_after_ms: u64,
    /// The board's first reading is waited for up to this long per request, ms (default 100).
    pub board_timeout_ms: u64,
    /// Node settings; `None`: defaults with the device's pressure thresholds.
    pub node: Option<VacuumNodeConfig>,
    /// Arm settings for the reachability test; `None`: the device's arm profile.
    pub arm_node: Option<ArmNodeConfig>,
}

impl Default for VacuumProcessConfig {
    fn default() -> Self {
        Self {
            control_period_us: 5000,
            complete_after_ms: 2000,
            board_timeout_ms: 100,
            node: None,
            arm_node: None,
        }
    }
}

impl VacuumProcessConfig {
    /// Reads and checks a settings file.
    pub fn from_path(path: &Path) -> Result<Self, VacuumProcessError> {
        let config: Self = read_toml(path, "vacuum settings")?;
        config.validate()?;
        Ok(config)
    }

    fn validate(&self) -> Result<(), VacuumProcessError> {
        let checks = [
            (
                "control_period_us",
                self.control_period_us,
                (500..=100_000).contains(&self.control_period_us),
                "500..=100000 (2 kHz to 10 Hz)",
            ),
            (
                "complete_after_ms",
                self.complete_after_ms,
                self.complete_after_ms > 0,
                "> 0",
            ),
            (
                "board_timeout_ms",
                self.board_timeout_ms,
                (1..=10_000).contains(&self.board_timeout_ms),
                "1..=10000",
            ),
        ];
        for (key, value, ok, expected) in checks {
            if !ok {
                return Err(VacuumProcessError::InvalidConfig {
                    key,
                    value,
                    expected,
                });
            }
        }
        Ok(())
    }
}

/// Why the vacuum process stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum VacuumProcessError {
    /// The settings file could not be read.
    #[error(transparent)]
    Config(#[from] ConfigFileError),
    /// A setting is out of range.
    #[error("vacuum settings: `{key}` = {value}: expected {expected}")]
    InvalidConfig {
        key: &'static str,
        value: u64,
        expected: &'static str,
    },
    /// The node refused its settings.
    #[error(transparent)]
    Node(#[from] VacuumNodeError),
    /// The period statistics could not be set up.
    #[error(transparent)]
    Period(#[from] PeriodStatsError),
    /// The valve board could not be reached or refused commands for too long.
    #[error("valve board: {0}")]
    Device(#[source] AnyDeviceError),
    /// `--device serial` without `--port`.
    #[error("--device serial needs --port PATH")]
    SerialWithoutPort,
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
}

harvest_ipc::from_ipc_errors!(VacuumProcessError);

/// Board exchanges failing in a row after which the process stops (and is restarted): 10 s.
const MAX_CONSECUTIVE_DEVICE_ERRORS: u32 = 2000;

/// Runs the vacuum supervisor until SIGINT/SIGTERM; returns its control period statistics.
pub fn run(
    args: &VacuumArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<PeriodSummary, VacuumProcessError> {
    let config = match &args.config {
        Some(path) => VacuumProcessConfig::from_path(path)?,
        None => VacuumProcessConfig::default(),
    };
    let mut node_config = config.node.unwrap_or(VacuumNodeConfig {
        pressure: args.device.pressure_config(),
        ..VacuumNodeConfig::default()
    });
    node_config.policy = args.policy.kind();
    node_config.arms_enabled = [true, args.arms >= 2];
    let arm_node = config
        .arm_node
        .unwrap_or_else(|| args.device.arm_node_config());
    let node = VacuumNode::new(
        node_config,
        Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
            pick_reachable(arm, *centre, radius_m, &arm_node)
        }),
    )?;
    let context = Context::new(domain, process_name)?;
    let timeout = Duration::from_millis(config.board_timeout_ms);
    match args.device {
        VacuumDevice::Sim => {
            let board = SimValveBoard::connect(&context, timeout)
                .map_err(|error| VacuumProcessError::Device(AnyDeviceError::new(error)))?;
            control_loop(&context, board, node, &config, args)
        }
        VacuumDevice::Serial => {
            let port = args
                .port
                .as_deref()
                .ok_or(VacuumProcessError::SerialWithoutPort)?;
            let board = SerialValveBoard::open(&SerialBoardConfig::new(port))
                .map_err(|error| VacuumProcessError::Device(AnyDeviceError::new(error)))?;
            control_loop(&context, board, node, &config, args)
        }
    }
}

/// Tracks whether the harvest of what the camera sees is complete (module docs).
#[derive(Debug, Clone, Copy, Default)]
struct CompletionWatch {
    /// Detection sets processed since the last attempt ended (or since the start).
    sets_since_attempt: u32,
    /// When the idle condition started to hold, ns.
    idle_since_ns: Option<u64>,
    /// `HarvestComplete` was published and nothing was assigned since.
    reported: bool,
}

impl CompletionWatch {
    fn on_event(&mut self, event: &VacuumNodeEvent) {
        match event {
            VacuumNodeEvent::Replanned { .. } => {
                self.sets_since_attempt = self.sets_since_attempt.saturating_add(1);
            }
            VacuumNodeEvent::AttemptFinished { .. } | VacuumNodeEvent::DispatchTimedOut { .. } => {
                self.sets_since_attempt = 0;
            }
            VacuumNodeEvent::TargetDispatched { .. } => {
                self.sets_since_attempt = 0;
                self.reported = false;
            }
            _ => {}
        }
    }

    /// True on the tick the harvest becomes complete.
    fn update(&mut self, now_ns: u64, idle: bool, after_ns: u64) -> bool {
        if !idle || self.sets_since_attempt == 0 {
            self.idle_since_ns = None;
            return false;
        }
        let since = *self.idle_since_ns.get_or_insert(now_ns);
        if !self.reported && now_ns.saturating_sub(since) >= after_ns {
            self.reported = true;
            return true;
        }
        false
    }
}

fn control_loop<B: ValveBoard>(
    context: &Context,
    mut board: B,
    mut node: VacuumNode,
    config: &VacuumProcessConfig,
    args: &VacuumArgs,
) -> Result<PeriodSummary, VacuumProcessError> {
    let apples_in = context.subscriber(PERCEPTION_APPLES)?;
    let state_in = [
        context.subscriber(ARM_STATE[0])?,
        context.subscriber(ARM_STATE[1])?,
    ];
    let request_in = context.subscriber(VALVE_REQUEST)?;
    let estop_in = context.subscriber(EMERGENCY_STOP)?;
    // The operator's mode: targets go out only while harvesting, to enabled arms (no mode
    // ever published: a stack without the executive harvests as before).
    let mode_in = context.subscriber(OPERATOR_MODE)?;
    let mut target_out = [
        context.publisher(ARM_TARGET[0])?,
        context.publisher(ARM_TARGET[1])?,
    ];
    let mut grant_out = context.publisher(VALVE_GRANT)?;
    let mut state_out = context.publisher(VACUUM_STATE)?;
    let mut events_out = context.publisher(HARVEST_EVENTS)?;
    let mut health = HealthReporter::new(context)?;

    let period_ns = config.control_period_us * 1000;
    let complete_after_ns = config.complete_after_ms * 1_000_000;

    let mut arm_states: [Option<ArmState>; 2] = [None; 2];
    let mut requests: [Option<ValveRequest>; 2] = [None; 2];
    let mut estop = false;
    // The position last sent to the board per valve; unknown until the first command.
    let mut applied: [Option<bool>; 4] = [None; 4];
    let mut device_errors = FailureStreak::new(MAX_CONSECUTIVE_DEVICE_ERRORS);
    let mut sets = 0u64;
    let mut completion = CompletionWatch::default();
    let enabled = [true, args.arms >= 2];
    tracing::info!(policy = ?args.policy, arms = args.arms, period_us = config.control_period_us,
        "vacuum supervisor running");
    let summary = run_control_loop(period_ns, |wake| -> Result<Flow, VacuumProcessError> {
        match wake {
            Wake::Tick { now_ns } => {
                // 1. The board.
                let readings = match read_board(&mut board, now_ns) {
                    Ok(readings) => {
                        device_errors.succeeded();
                        Some(readings)
                    }
                    Err(error) => {
                        health.note_device_error(error.kind().into());
                        if device_errors.failed("valve board read", &error).is_some() {
                            return Err(VacuumProcessError::Device(error));
                        }
                        None
                    }
                };

                // 2. Channels.
                let detections = apples_in.receive_latest()?;
                sets += u64::from(detections.is_some());
                for (i, subscriber) in state_in.iter().enumerate() {
                    if let Some(state) = subscriber.receive_latest()? {
                        arm_states[i] = Some(*state);
                    }
                }
                while let Some(request) = request_in.receive()? {
                    if let Some(slot) = match request.arm_id {
                        1 => Some(0),
                        2 => Some(1),
                        _ => None,
                    } {
                        requests[slot] = Some(*request);
                    }
                }
                if let Some(sample) = estop_in.receive_latest()? {
                    estop = sample.engaged != 0;
                }
                if let Some(mode) = mode_in.receive_latest()? {
                    let harvesting = mode.mode_code()
                        == Some(harvest_ipc::payloads::OperatorModeCode::Harvesting);
                    // The row's stop cycle holds new approaches while it repositions.
                    let held = !harvesting || mode.field_hold != 0;
                    node.hold_dispatch(mode.arms_enabled.map(|on| held || on == 0));
                }

                // 3. The node.
                let input = harvest_vacuum::node::VacuumNodeInput {
                    now_ns,
                    arm_states: [arm_states[0].as_ref(), arm_states[1].as_ref()],
                    valve_requests: [requests[0].as_ref(), requests[1].as_ref()],
                    readings,
                    detections: detections.as_deref(),
                    emergency_stop: estop,
                };
                let out = node.step(&input);
                drop(detections);

                // 4. The valves.
                if out.close_all {
                    match board.close_all() {
                        Ok(()) => applied = [Some(false); 4],
                        Err(error) => {
                            tracing::error!(%error, "close_all refused by the board");
                            health.note_device_error(error.kind().into());
                        }
                    }
                }
                for (k, &open) in out.valve_commands.iter().enumerate() {
                    if applied[k] == Some(open) {
                        continue;
                    }
                    match board.set_valve(ValveId(k as u8 + 1), open) {
                        Ok(()) => applied[k] = Some(open),
                        // Retried next tick (the position stays unknown).
                        Err(error) => {
                            applied[k] = None;
                            tracing::warn!(%error, valve = k + 1, open, "valve command failed");
                            health.note_device_error(error.kind().into());
                        }
                    }
                }

                // 5. Outputs.
                for (i, target) in out.targets.iter().enumerate() {
                    if let Some(target) = target {
                        target_out[i].publish(target)?;
                    }
                }
                for grant in out.grants.iter().flatten() {
                    grant_out.publish(grant)?;
                }
                state_out.publish(&out.state)?;
                let arms = ArmContext {
                    phase: arm_states.map(|s| s.map_or(PhaseCode::Idle.into(), |s| s.phase)),
                    apple_id: arm_states.map(|s| s.map_or(0, |s| s.apple_id)),
                };
                for event in &out.events {
                    completion.on_event(event);
                    if let Some(harvest_event) = vacuum_event(now_ns, event, &arms) {
                        if harvest_event.kind == HarvestEventKind::Assigned {
                            tracing::info!(arm = harvest_event.arm_id,
                                apple_id = harvest_event.apple_id,
                                position_m = ?harvest_event.position_in_robot_m, "apple assigned");
                        }
                        events_out.publish(&harvest_event)?;
                    }
                }
                let arms_idle = (0..2).all(|i| {
                    !enabled[i] || arm_states[i].is_some_and(|s| s.phase == PhaseCode::Idle)
                });
                if completion.update(now_ns, arms_idle && node.is_idle(), complete_after_ns) {
                    tracing::info!("harvest complete: nothing left to pick");
                    let mut event = HarvestEvent::new(
                        now_ns,
                        HarvestEventSource::Vacuum,
                        HarvestEventKind::HarvestComplete,
                        0,
                        0,
                    );
                    event.reason = FixedString::new("nothing assigned, dispatched or running");
                    events_out.publish(&event)?;
                }
            }
            Wake::Heartbeat { period } => {
                let state = device_errors.run_state();
                health.report_control_loop(state, sets, &period)?;
            }
        }
        Ok(Flow::Continue)
    })?;

    // Leave every tube vented and cut off from the source.
    if let Err(error) = board.close_all() {
        tracing::warn!(%error, "final close_all failed");
    }
    tracing::info!(
        detection_sets = sets,
        device_errors = device_errors.total(),
        p50_us = summary.p50_ns / 1000,
        p99_us = summary.p99_ns / 1000,
        max_us = summary.max_ns / 1000,
        "vacuum supervisor stopped; control period: {summary}"
    );
    Ok(summary)
}

/// One board report as the node takes it.
fn read_board<B: ValveBoard>(board: &mut B, now_ns: u64) -> Result<BoardReadings, AnyDeviceError> {
    let states = board.valve_states().map_err(AnyDeviceError::new)?;
    let pressures = board.pressures().map_err(AnyDeviceError::new)?;
    Ok(BoardReadings {
        stamp_ns: now_ns,
        valve_open: states
            .0
            .map(|s| matches!(s, ValveState::Open | ValveState::Opening)),
        valve_in_transit: states.0.map(ValveState::is_in_transit),
        pressure_mmh2o: pressures.to_array(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_with_defaults_and_refuse_unknown_keys() {
        let config: VacuumProcessConfig = toml::from_str("complete_after_ms = 500").expect("parse");
        assert_eq!(config.complete_after_ms, 500);
        assert_eq!(config.control_period_us, 5000);
        assert!(toml::from_str::<VacuumProcessConfig>("complete_after = 1").is_err());
        let bad = VacuumProcessConfig {
            board_timeout_ms: 0,
            ..VacuumProcessConfig::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(VacuumProcessError::InvalidConfig {
                key: "board_timeout_ms",
                ..
            })
        ));
    }

    #[test]
    fn the_sim_thresholds_are_valid_and_separate_an_open_cup_from_a_seal() {
        let pressure = VacuumDevice::Sim.pressure_config();
        assert_eq!(pressure.validate(), Ok(()));
        assert_eq!(pressure.attach_timeout_ns, SIM_ATTACH_TIMEOUT_NS);
        // The simulator's default valve box: inlet 0.5, bare cup 0.3, sealed cup 0.005.
        let open_cup_ratio = 0.5f32 / (0.5 + 0.3);
        let sealed_ratio = 0.5f32 / (0.5 + 0.005);
        assert!(pressure.seal_ratio_off > open_cup_ratio, "{pressure:?}");
        assert!(pressure.seal_ratio_off < pressure.seal_ratio_on);
        assert!(pressure.seal_ratio_on < sealed_ratio, "{pressure:?}");
    }

    #[test]
    fn completion_needs_a_fresh_detection_set_and_the_idle_time() {
        let mut watch = CompletionWatch::default();
        let ms = 1_000_000;
        // Idle from the start but no detection set yet: not complete.
        assert!(!watch.update(0, true, 100 * ms));
        assert!(!watch.update(200 * ms, true, 100 * ms));
        let replanned = VacuumNodeEvent::Replanned {
            summary: harvest_vacuum::replan::ReplanSummary::default(),
            queued: [0, 0],
            invalid: 0,
            given_up: 0,
        };
        watch.on_event(&replanned);
        assert!(!watch.update(300 * ms, true, 100 * ms));
        assert!(!watch.update(350 * ms, false, 100 * ms));
        assert!(!watch.update(360 * ms, true, 100 * ms));
        assert!(watch.update(460 * ms, true, 100 * ms));
        // Reported once.
        assert!(!watch.update(600 * ms, true, 100 * ms));
    }
}
