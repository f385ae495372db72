//! harvest-runtime: runs a [`harvest_node::Node`] as a process on the iceoryx2 channels of the
//! catalogue.
//!
//! What it adds to the tick of [`harvest_node::Runner`] (read the stop, make safe, read the
//! devices, obey the mode, read the inputs, step, write, publish): the ports, opened from the
//! node's declared inputs and outputs ([`IpcTransport`]; large messages read and written in
//! place in shared memory, [`harvest_node::in_place`]); the wake-up, never a sleep or a poll:
//! [`run_node`] ticks on a kernel periodic timer ([`harvest_ipc::control_loop`]: tick-to-tick
//! intervals and deadline misses measured), [`run_on_wake`] on an input's iceoryx2 event
//! ([`Wake::Input`]: a wait set, then back to back while the node has more work,
//! [`Node::has_more_work`]) or back to back on a device that paces the node
//! ([`Wake::Device`]: the step blocks in the driver's event-driven capture, bounded); the
//! heartbeat on `system/health` (run state degraded while a device exchange fails, the
//! period's p99 and the deadline misses, or what the node says, [`Node::health`]); and the
//! end of the run on SIGINT/SIGTERM or an error, always with the devices in their safe state
//! first.

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

mod in_place;
mod transport;
mod wake;

pub use transport::IpcTransport;
pub use wake::{Wake, WakeOptions, run_on_wake};

use harvest_hw::AnyDeviceError;
use harvest_ipc::catalogue::Channel;
use harvest_ipc::control_loop::{Wake as TimerWake, run_control_loop};
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::NodeTickRecord;
use harvest_ipc::period_stats::{PeriodStatsError, PeriodSummary};
use harvest_ipc::{Context, Flow, HealthReporter, MonotonicClock};
use harvest_node::{Devices, Node, Runner, RunnerConfig, TickError};

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
    /// [`Wake::Input`] names a channel the node does not read.
    #[error("{node}: woken by {topic}, which is not one of its inputs")]
    NoSuchInput { node: String, topic: &'static str },
    /// The SIGINT/SIGTERM handler could not be installed.
    #[error("installing the signal handler: {0}")]
    Signal(#[from] std::io::Error),
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

/// A run that ended: its summary (the period statistics of a periodic run, the ticks of a
/// woken one) and the runner (the node and its devices, for the caller's last log line), or
/// the error that ended it.
pub struct Finished<N: Node, S = PeriodSummary> {
    pub runner: Runner<N>,
    pub result: Result<S, RunError>,
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
    run_periodic(
        context,
        Runner::new(node, devices, options.runner),
        options,
        None,
    )
}

/// [`run_node`], and after every tick what it saw ([`harvest_node::tick_record`]: the stop,
/// the mode, the device readings, the messages read) published on `ticks`, so that a
/// recording can re-run the node (`harvest replay --check`).
pub fn run_node_recording_ticks<N: Node>(
    context: &Context,
    node: N,
    devices: N::Devices,
    options: RunOptions,
    ticks: Channel<NodeTickRecord>,
) -> Result<Finished<N>, RunError>
where
    <N::Devices as Devices>::Readings: serde::Serialize,
{
    let mut runner = Runner::new(node, devices, options.runner);
    runner.record_ticks();
    run_periodic(context, runner, options, Some(ticks))
}

fn run_periodic<N: Node>(
    context: &Context,
    mut runner: Runner<N>,
    options: RunOptions,
    ticks: Option<Channel<NodeTickRecord>>,
) -> Result<Finished<N>, RunError> {
    let (inputs, outputs) = runner.slots_mut();
    let mut transport = IpcTransport::open(context, inputs, outputs)?;
    let mut health = HealthReporter::new(context)?;
    let mut tick_publisher = ticks
        .map(|channel| context.publisher(channel))
        .transpose()?;
    tracing::info!(
        node = runner.node().name(),
        period_us = options.period_ns / 1000,
        records_ticks = tick_publisher.is_some(),
        "running"
    );
    let mut records_unsent = 0u64;
    let result = run_control_loop(options.period_ns, |wake| -> Result<Flow, RunError> {
        match wake {
            TimerWake::Tick { now_ns } => {
                let ticked = runner.tick(&mut transport, now_ns);
                // The record goes out for a tick that ended the run too; a record that cannot
                // be sent never stops the node.
                if let (Some(publisher), Some(record)) = (&mut tick_publisher, runner.tick_record())
                    && let Err(error) = publisher.publish(record)
                {
                    records_unsent += 1;
                    if records_unsent == 1 {
                        tracing::warn!(%error, "tick record not sent (counted; the node goes on)");
                    }
                }
                ticked?;
            }
            TimerWake::Heartbeat { period } => heartbeat(&mut health, &mut runner, Some(&period))?,
        }
        Ok(Flow::Continue)
    });
    if records_unsent > 0 {
        tracing::warn!(records_unsent, "tick records not sent during the run");
    }
    if let Err(error) = runner.shutdown(&mut transport, MonotonicClock::read_ns()) {
        tracing::warn!(%error, "last messages not sent");
    }
    Ok(Finished { runner, result })
}

/// One heartbeat: what the node says ([`Node::health`]) or the runner's run state, with the
/// period's p99 and deadline misses for a periodic run (`period`) or the ticks so far.
pub(crate) fn heartbeat<N: Node>(
    health: &mut HealthReporter,
    runner: &mut Runner<N>,
    period: Option<&PeriodSummary>,
) -> Result<(), IpcError> {
    let progress = runner.node().progress().unwrap_or(runner.ticks());
    if let Some(kind) = runner.last_device_error() {
        health.note_device_error(kind.into());
    }
    let said = runner.node_mut().health();
    if let Some(kind) = said.and_then(|said| said.device_error) {
        health.note_device_error(kind.into());
    }
    match (said, period) {
        (Some(said), _) => health.report(said.state, progress, said.detail, said.value)?,
        (None, Some(period)) => health.report_control_loop(runner.run_state(), progress, period)?,
        (None, None) => health.report(runner.run_state(), progress, "ticks", runner.ticks())?,
    }
    Ok(())
}
