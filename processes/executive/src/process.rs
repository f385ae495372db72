//! `harvest executive`: the operator's mode machine on the node runtime:
//! [`ExecutiveNode`] (`harvest_executive_node`: the executive between its channels and its
//! devices, and along a row the stop-and-go cycle) under [`run_node`], every
//! `--control-period-us` (200 Hz by default) on a kernel periodic timer.
//!
//! What happens each tick is the node's (its module documentation): the safety monitor's stop
//! requests and the operator's commands through `harvest_operator::Executive`, the emergency
//! stop, manual orders, the platform, the row, `operator/mode` at 10 Hz and on every change.
//! This main reads the control token (`$HARVEST_CONTROL_TOKEN`, set by `harvest up`, else the
//! domain's token file) and the mode an earlier executive of the same run left in the mode file
//! (`harvest_operator::mode_file`, so a crash does not resume a paused harvest), and chooses the
//! devices: the platform (`--platform sim|none`) and, with `--row-stops N`, the simulated
//! tractor. A silent platform never ends the executive (it is the emergency stop's one writer):
//! its failed polls are counted on the heartbeat.

use std::path::PathBuf;
use std::time::Duration;

use harvest_executive_node::{
    ExecutiveDevices, ExecutiveNode, ExecutiveNodeConfig, ModeStore, RowOptions,
};
use harvest_field::StopCycleError;
use harvest_hw::AnyDeviceError;
use harvest_hw::platform::PlatformTravel;
use harvest_hw::platform::sim::SimPlatform;
use harvest_hw::tractor::sim::SimTractor;
use harvest_ipc::payloads::{OperatorModeCode, OperatorModeState};
use harvest_ipc::{Context, Domain};
use harvest_node::RunnerConfig;
use harvest_operator::mode_file::{load_mode, mode_path};
use harvest_operator::token::{CONTROL_TOKEN_ENV, TokenError, read_token_file, token_path};
use harvest_operator::{ControlToken, ExecutiveConfig};
use harvest_robot_model::ModeSource;
use harvest_runtime::{RunError, RunOptions, run_node};

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
    /// The run ended on an error.
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(ExecutiveProcessError);

/// The platform driver waits this long for its first feedback, and refuses older feedback.
const PLATFORM_TIMEOUT: Duration = Duration::from_millis(100);
/// How long the tractor driver waits for its first feedback.
const TRACTOR_TIMEOUT: Duration = Duration::from_secs(5);

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
    let previous = load_mode(&mode_file, &token).map(|(mode, arms)| OperatorModeState {
        mode: mode as u8,
        arms_enabled: arms.map(u8::from),
        ..OperatorModeState::default()
    });
    let context = Context::new(domain, process_name)?;
    let platform = match args.platform {
        PlatformDevice::Sim => Some(
            SimPlatform::connect(&context, PlatformTravel::default(), PLATFORM_TIMEOUT)
                .map_err(|error| ExecutiveProcessError::Platform(AnyDeviceError::new(error)))?,
        ),
        PlatformDevice::None => None,
    };
    let row = (args.row_stops > 0).then_some(RowOptions {
        stops: args.row_stops,
        stop_spacing_m: args.stop_spacing_m,
        auto_advance: args.auto_advance,
        quiet_ns: args.stop_quiet_ms * 1_000_000,
    });
    let tractor = match row {
        Some(_) => Some(
            SimTractor::connect(&context, TRACTOR_TIMEOUT)
                .map_err(|error| ExecutiveProcessError::Tractor(AnyDeviceError::new(error)))?,
        ),
        None => None,
    };
    let mode_store = ModeStore {
        path: mode_file,
        token: token.clone(),
    };
    let devices = ExecutiveDevices::new(platform, tractor, Some(mode_store));
    // The row is positioned within the default stages' travel, as the platform's driver is
    // built with it (also without a platform, where the row cannot run anyway).
    let travel = PlatformTravel::default();
    let config = ExecutiveNodeConfig {
        executive: ExecutiveConfig {
            initial_mode: match args.initial_mode {
                InitialMode::Idle => OperatorModeCode::Idle,
                InitialMode::Harvesting => OperatorModeCode::Harvesting,
            },
            ..ExecutiveConfig::default()
        },
        token,
        previous,
        row,
        travel_max_m: [travel.in_out_max_m, travel.up_down_max_m],
    };
    let node = ExecutiveNode::new(config, &devices)?;
    tracing::info!(period_us = args.control_period_us, platform = ?args.platform,
        initial_mode = ?args.initial_mode, "executive running");
    let options = RunOptions {
        period_ns: args.control_period_us * 1000,
        runner: RunnerConfig {
            // The emergency stop's one writer never ends on a silent platform.
            max_read_failures: u32::MAX,
            // The executive decides the mode; it obeys none.
            mode_source: ModeSource::WithoutOperator,
        },
    };
    let finished = run_node(&context, node, devices, options)?;
    finished.result?;
    tracing::info!(
        commands = finished.runner.node().handled(),
        "executive stopped"
    );
    Ok(())
}
