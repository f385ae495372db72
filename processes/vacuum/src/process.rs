//! `harvest vacuum`: the vacuum supervisor's 200 Hz loop over the channels (valves, pressure
//! inference, coordination policy, apple assignment): [`VacuumTask`] (`harvest_vacuum::task`:
//! `VacuumNode` between its channels and the valve board) under the node runtime
//! ([`run_node_recording_ticks`]: each tick's record on `vacuum/ticks`), every
//! [`VacuumProcessConfig::control_period_us`] on a kernel periodic timer.
//!
//! The tick is the runtime's (`harvest_node::Runner::tick`, the one `harvest eval harvest` runs
//! in process): `safety/emergency_stop` first
//! (engaged: `close_all` before anything else, repeated each tick until the board takes it);
//! the board through [`ValveBoard`] (valve states, the three pressures; a failed read leaves
//! the valves as they are, so a carried apple is not dropped); `operator/mode` by the stack's
//! one rule ([`harvest_robot_model::obedience`](mod@harvest_robot_model::obedience): targets only while harvesting, outside the
//! row's field hold, to enabled arms; no mode heard means hold unless `--without-operator`);
//! the newest detection set, both arms' states and their standing valve requests;
//! `VacuumNode::step` with the reachability from the arm kinematics
//! ([`harvest_arm::node::pick_reachable`], the evaluation's test); the valves whose position
//! changed; then `armN/target`, `vacuum/valve_grant`, `vacuum/state` and `harvest/events`.
//!
//! When nothing is left to do for [`VacuumProcessConfig::complete_after_ms`]
//! (`harvest_vacuum::completion::CompletionWatch`), a `HarvestComplete` event is published once;
//! `harvest up --until-harvested` stops the stack on it. However the loop ends every valve is
//! closed. The device is chosen in one place, [`run`] (`--device sim`: the simulated valve board
//! behind `hw/valves/command|readings`; `--device serial`), with the pressure thresholds
//! calibrated for it ([`VacuumDevice::pressure_config`]).

use std::path::{Path, PathBuf};
use std::time::Duration;

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_hw::AnyDeviceError;
use harvest_hw::valve_board::ValveBoard;
use harvest_hw::valve_board::serial::{SerialBoardConfig, SerialValveBoard};
use harvest_hw::valve_board::sim::SimValveBoard;
use harvest_ipc::catalogue::VACUUM_TICKS;
use harvest_ipc::config_file::{ConfigFileError, read_toml};
use harvest_ipc::period_stats::{PeriodStatsError, PeriodSummary};
use harvest_ipc::{Context, Domain};
use harvest_node::RunnerConfig;
use harvest_robot_model::{ArmId, ModeSource};
use harvest_runtime::{RunError, RunOptions, run_node_recording_ticks};
use harvest_vacuum::node::{VacuumNode, VacuumNodeConfig, VacuumNodeError};
use harvest_vacuum::pressure::PressureConfig;
use serde::Deserialize;

use crate::policy_arg::PolicyArg;
use harvest_vacuum::task::{BoardDevices, VacuumTask};

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
    /// No executive runs in this stack (a bench profile, a test): until an `operator/mode` is
    /// heard, dispatch targets. Without it, no mode heard means hold.
    #[arg(long)]
    pub without_operator: bool,
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
    /// Control period, us (default 5000: 200 Hz, [dual-arm sec. 2.2]).
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
            complete_after_ms: harvest_vacuum::completion::DEFAULT_COMPLETE_AFTER_MS,
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
    /// The run ended on an error (transport, too many failed board reads in a row).
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(VacuumProcessError);

/// Board exchanges failing in a row after which the process stops (and is restarted): 10 s.
pub const MAX_CONSECUTIVE_DEVICE_ERRORS: u32 = 2000;

/// The process settings and the node `args` give.
fn settings(args: &VacuumArgs) -> Result<(VacuumProcessConfig, VacuumNode), VacuumProcessError> {
    let config = match &args.config {
        Some(path) => VacuumProcessConfig::from_path(path)?,
        None => VacuumProcessConfig::default(),
    };
    let mut node_config = config.node.unwrap_or(VacuumNodeConfig {
        pressure: args.device.pressure_config(),
        ..VacuumNodeConfig::default()
    });
    node_config.policy = args.policy.kind();
    node_config.arms_enabled = enabled_arms(args);
    let arm_node = config
        .arm_node
        .unwrap_or_else(|| args.device.arm_node_config());
    let node = VacuumNode::new(
        node_config,
        Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
            pick_reachable(arm, *centre, radius_m, &arm_node)
        }),
    )?;
    Ok((config, node))
}

/// The task [`run`] runs for `args`, on a valve board of type `B` (`harvest replay --check`
/// re-runs it on a recorded board).
pub fn task<B: ValveBoard>(args: &VacuumArgs) -> Result<VacuumTask<B>, VacuumProcessError> {
    let (config, node) = settings(args)?;
    Ok(VacuumTask::new(
        node,
        enabled_arms(args),
        config.complete_after_ms,
    ))
}

fn enabled_arms(args: &VacuumArgs) -> [bool; 2] {
    [true, args.arms >= 2]
}

/// Runs the vacuum supervisor until SIGINT/SIGTERM; returns its control period statistics.
pub fn run(
    args: &VacuumArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<PeriodSummary, VacuumProcessError> {
    let (config, node) = settings(args)?;
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

/// The control loop of [`run`] on the given board: [`VacuumTask`] under the node runtime
/// ([`run_node_recording_ticks`]) until SIGINT/SIGTERM or an error.
pub fn control_loop<B: ValveBoard>(
    context: &Context,
    board: B,
    node: VacuumNode,
    config: &VacuumProcessConfig,
    args: &VacuumArgs,
) -> Result<PeriodSummary, VacuumProcessError> {
    let task = VacuumTask::<B>::new(node, enabled_arms(args), config.complete_after_ms);
    let mode_source = if args.without_operator {
        ModeSource::WithoutOperator
    } else {
        ModeSource::Executive
    };
    let options = RunOptions {
        period_ns: config.control_period_us * 1000,
        runner: RunnerConfig {
            max_read_failures: MAX_CONSECUTIVE_DEVICE_ERRORS,
            mode_source,
        },
    };
    tracing::info!(policy = ?args.policy, arms = args.arms, ?mode_source, "vacuum supervisor");
    let finished = run_node_recording_ticks(
        context,
        task,
        BoardDevices::new(board),
        options,
        VACUUM_TICKS,
    )?;
    let summary = finished.result?;
    let (read_failures, write_failures) = finished.runner.device_failures();
    tracing::info!(
        detection_sets = finished.runner.node().sets(),
        read_failures,
        write_failures,
        p50_us = summary.p50_ns / 1000,
        p99_us = summary.p99_ns / 1000,
        max_us = summary.max_ns / 1000,
        "vacuum supervisor stopped; control period: {summary}"
    );
    Ok(summary)
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
}
