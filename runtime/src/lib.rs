//! harvest-runtime: [`run_node`] runs a [`harvest_node::Node`] as a process on the iceoryx2
//! channels of the catalogue.
//!
//! What it adds to the tick of [`harvest_node::Runner`] (read the stop, make safe, read the
//! devices, obey the mode, read the inputs, step, write, publish): the ports, opened from the
//! node's declared inputs and outputs ([`IpcTransport`]); the periodic control loop on a kernel
//! timer ([`harvest_ipc::control_loop`]: no sleeps, tick-to-tick intervals and deadline misses
//! measured); the heartbeat on `system/health` (run state degraded while a device exchange
//! fails, the period's p99 and the deadline misses); and the end of the run on SIGINT/SIGTERM or
//! an error, always with the devices in their safe state first.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

mod transport;

pub use transport::IpcTransport;

use harvest_hw::AnyDeviceError;
use harvest_ipc::control_loop::{Wake, run_control_loop};
use harvest_ipc::error::IpcError;
use harvest_ipc::period_stats::{PeriodStatsError, PeriodSummary};
use harvest_ipc::{Context, Flow, HealthReporter, MonotonicClock};
use harvest_node::{Node, Runner, RunnerConfig, TickError};

/// How a node is run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunOptions {
    /// The tick period, ns (the node is woken on a periodic timer).
    pub period_ns: u64,
    pub runner: RunnerConfig,
}

/// Why a run ended with an error.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The transport (node, channel, send, receive, timer) failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The period statistics could not be set up.
    #[error(transparent)]
    Period(#[from] PeriodStatsError),
    /// The node failed for good.
    #[error("{node}: {message}")]
    Node { node: String, message: String },
    /// The devices failed to answer too many times in a row.
    #[error("{node}: {failures} device reads failed in a row: {error}")]
    Device {
        node: String,
        failures: u32,
        /// The last read's error, with its kind.
        #[source]
        error: AnyDeviceError,
    },
}

harvest_ipc::from_ipc_errors!(RunError);

impl<N: std::error::Error> From<TickError<IpcError, N>> for RunError {
    fn from(error: TickError<IpcError, N>) -> Self {
        match error {
            TickError::Transport(error) => Self::Ipc(error),
            TickError::Node { node, error } => Self::Node {
                node,
                message: error.to_string(),
            },
            TickError::Device {
                node,
                failures,
                error,
            } => Self::Device {
                node,
                failures,
                error,
            },
        }
    }
}

/// A run that ended: the period statistics and the runner (the node and its devices, for the
/// caller's last log line), or the error that ended it.
pub struct Finished<N: Node> {
    pub runner: Runner<N>,
    pub result: Result<PeriodSummary, RunError>,
}

/// Runs `node` with its `devices` every `options.period_ns` until SIGINT/SIGTERM or an error
/// (crate documentation). The devices are put in their safe state and the node's last
/// messages sent however the run ends.
pub fn run_node<N: Node>(
    context: &Context,
    node: N,
    devices: N::Devices,
    options: RunOptions,
) -> Result<Finished<N>, RunError> {
    let mut runner = Runner::new(node, devices, options.runner);
    let (inputs, outputs) = runner.slots_mut();
    let mut transport = IpcTransport::open(context, inputs, outputs)?;
    let mut health = HealthReporter::new(context)?;
    tracing::info!(
        node = runner.node().name(),
        period_us = options.period_ns / 1000,
        "running"
    );
    let result = run_control_loop(options.period_ns, |wake| -> Result<Flow, RunError> {
        match wake {
            Wake::Tick { now_ns } => runner.tick(&mut transport, now_ns)?,
            Wake::Heartbeat { period } => {
                let progress = runner.node().progress().unwrap_or(runner.ticks());
                if let Some(kind) = runner.last_device_error() {
                    health.note_device_error(kind.into());
                }
                health.report_control_loop(runner.run_state(), progress, &period)?;
            }
        }
        Ok(Flow::Continue)
    });
    if let Err(error) = runner.shutdown(&mut transport, MonotonicClock::read_ns()) {
        tracing::warn!(%error, "last messages not sent");
    }
    Ok(Finished { runner, result })
}
