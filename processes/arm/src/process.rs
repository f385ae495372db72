//! `harvest arm --id 1|2`: one arm's 200 Hz control loop over the channels: [`ArmTask`]
//! (`harvest_arm::task`: `ArmNode` between its channels and its servos) under the node runtime
//! ([`run_node_recording_ticks`]: each tick's record on `armN/ticks`), every
//! [`ArmProcessConfig::control_period_us`] on a kernel periodic timer.
//!
//! The tick is the runtime's (`harvest_node::Runner::tick`, the one `harvest eval harvest` runs
//! in process): `safety/emergency_stop` first
//! (engaged: the servos brake before anything else); the encoders through [`ArmServos`] (a
//! failed read brakes too; the node still steps, without fresh feedback, so that a stop reaches
//! the picking cycle); `operator/mode` by the stack's one rule
//! ([`harvest_robot_model::obedience`](mod@harvest_robot_model::obedience), `field_hold` included; no mode heard means hold unless
//! `--without-operator`); this arm's target, `vacuum/state`, its `vacuum/valve_grant` answers,
//! the other arm's state and target and its `armN/manual` orders; `ArmNode::step`; the servo
//! order written unless the arm was braked (a refused set-point brakes instead); then
//! `harvest/events`, `armN/command` (saying whether the arm holds), `armN/state` and the
//! standing `vacuum/valve_request` (on change, and re-sent every
//! [`ArmProcessConfig::valve_request_resend_ms`] so a restarted vacuum supervisor learns it).
//! Manual orders run in manual mode only; a manual move stops when the mode leaves manual or
//! is not heard for [`MODE_STALE_NS`]. Until the servos report for the first time the arm is
//! not ready: nothing is stepped or published.
//!
//! The heartbeat carries the period's p99 and deadline misses, degraded while the servos fail;
//! the full distribution is logged at the end. However the loop ends (SIGTERM, an error) the arm
//! brakes and asks for its valve to be closed. The device is chosen in one place, [`run`]
//! (`--device sim`: the simulated servos behind `hw/armN/servo|encoders`), with its timing
//! profile ([`ArmDevice::node_config`]).

use std::path::{Path, PathBuf};

use harvest_arm::node::{ArmNode, ArmNodeConfig, ArmNodeError};
use harvest_hw::AnyDeviceError;
use harvest_hw::arm_servos::ArmServos;
use harvest_hw::arm_servos::sim::SimArmServos;
use harvest_ipc::catalogue::ARM_TICKS;
use harvest_ipc::config_file::{ConfigFileError, read_toml};
use harvest_ipc::period_stats::{PeriodStatsError, PeriodSummary};
use harvest_ipc::{Context, Domain};
use harvest_node::RunnerConfig;
use harvest_robot_model::ModeSource;
use harvest_robot_model::params::{ArmId, ArmParams};
use harvest_runtime::{RunError, RunOptions, run_node_recording_ticks};
use serde::Deserialize;

use harvest_arm::task::{ArmDevices, ArmTask};

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
    /// No executive runs in this stack (a bench profile, a test): until an `operator/mode` is
    /// heard, take up targets. Without it, no mode heard means hold.
    #[arg(long)]
    pub without_operator: bool,
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
    /// Control period, us (default 5000: 200 Hz, [dual-arm sec. 2.2]).
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
            valve_request_resend_ms: harvest_arm::task::DEFAULT_VALVE_REQUEST_RESEND_MS,
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
    /// The servo device could not be reached.
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
    /// The run ended on an error (transport, too many failed encoder reads in a row).
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(ArmProcessError);

pub use harvest_robot_model::obedience::MODE_STALE_NS;

/// Device errors in a row after which the process stops (and the supervisor restarts it).
pub const MAX_CONSECUTIVE_DEVICE_ERRORS: u32 = 200;

/// The arm, its process settings and its node settings as `args` give them.
fn settings(args: &ArmArgs) -> Result<(ArmId, ArmProcessConfig, ArmNodeConfig), ArmProcessError> {
    let config = match &args.config {
        Some(path) => ArmProcessConfig::from_path(path)?,
        None => ArmProcessConfig::default(),
    };
    let arm = match args.id {
        1 => ArmId::Arm1,
        _ => ArmId::Arm2,
    };
    let node_config = config.node.unwrap_or_else(|| args.device.node_config());
    Ok((arm, config, node_config))
}

/// The task [`run`] runs for `args`, on servos of type `S` (`harvest replay --check` re-runs
/// it on recorded servos).
pub fn task<S: ArmServos>(args: &ArmArgs) -> Result<ArmTask<S>, ArmProcessError> {
    let (arm, config, node_config) = settings(args)?;
    let node = ArmNode::new(arm, node_config)?;
    Ok(ArmTask::new(node, config.valve_request_resend_ms))
}

/// Runs arm `args.id` until SIGINT/SIGTERM; returns its control period statistics.
pub fn run(
    args: &ArmArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<PeriodSummary, ArmProcessError> {
    let (arm, config, node_config) = settings(args)?;
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
            let mode_source = if args.without_operator {
                ModeSource::WithoutOperator
            } else {
                ModeSource::Executive
            };
            control_loop(&context, servos, arm, &config, node_config, mode_source)
        }
    }
}

/// The control loop of [`run`] on the given servos (a test drives it with a servo double):
/// [`ArmTask`] under the node runtime ([`run_node_recording_ticks`]) until SIGINT/SIGTERM or
/// an error.
pub fn control_loop<S: ArmServos>(
    context: &Context,
    servos: S,
    arm: ArmId,
    config: &ArmProcessConfig,
    node_config: ArmNodeConfig,
    mode_source: ModeSource,
) -> Result<PeriodSummary, ArmProcessError> {
    let node = ArmNode::new(arm, node_config)?;
    let task = ArmTask::<S>::new(node, config.valve_request_resend_ms);
    let options = RunOptions {
        period_ns: config.control_period_us * 1000,
        runner: RunnerConfig {
            max_read_failures: MAX_CONSECUTIVE_DEVICE_ERRORS,
            mode_source,
        },
    };
    let finished = run_node_recording_ticks(
        context,
        task,
        ArmDevices(servos),
        options,
        ARM_TICKS[arm.index()],
    )?;
    let summary = finished.result?;
    let (read_failures, write_failures) = finished.runner.device_failures();
    tracing::info!(
        arm = %arm,
        harvested = finished.runner.node().node().harvested_count(),
        read_failures,
        write_failures,
        p50_us = summary.p50_ns / 1000,
        p99_us = summary.p99_ns / 1000,
        max_us = summary.max_ns / 1000,
        "arm stopped; control period: {summary}"
    );
    Ok(summary)
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
