//! [`run_on_wake`]: a node woken by what it waits for, not by a clock: a sample on one of its
//! inputs ([`Wake::Input`], an iceoryx2 wait set on the channel's event service; ticked again
//! at once while the node has more work, [`Node::has_more_work`]), or its own device
//! ([`Wake::Device`]). The heartbeat goes out every [`HEARTBEAT_PERIOD`] either way.

use std::sync::atomic::{AtomicBool, Ordering};

use harvest_ipc::{Context, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Waiter};
use harvest_node::{Node, Runner, RunnerConfig};
use harvest_robot_model::ModeSource;

use crate::{Finished, IpcTransport, RunError, heartbeat};

/// What wakes a node run by [`run_on_wake`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// A sample on this input channel (one of the node's declared inputs): the node sleeps in
    /// a wait set on the channel's event service until the publisher's notification.
    /// Perception wakes on `camera/rgbd` this way. While the node says it has more work
    /// ([`Node::has_more_work`]) the runtime ticks it again at once, without waiting, sending
    /// the heartbeat between ticks when it is due and ending the run between ticks on a
    /// signal or `stop`: the laser answers a request with one device exchange per tick this
    /// way.
    Input { topic: &'static str },
    /// The node's own device paces it: the runtime ticks again as soon as a tick ends, and the
    /// step blocks in the driver's capture (event-driven in the driver, bounded by the node's
    /// timeout so that the heartbeat and a signal are seen). The camera and the LiDAR run
    /// this way.
    Device,
}

/// How [`run_on_wake`] runs a node.
#[derive(Debug, Clone, Copy)]
pub struct WakeOptions<'a> {
    pub wake: Wake,
    pub runner: RunnerConfig,
    /// Whether the node reads the emergency stop and the operator's mode (a node that drives
    /// actuators); a sensor or perception does not, and takes no reader's place on them.
    pub obeys: bool,
    /// Ends the run once set (checked at each heartbeat, and at each tick of
    /// [`Wake::Device`]): tests run a process's loop on a thread.
    pub stop: Option<&'a AtomicBool>,
}

impl WakeOptions<'_> {
    /// A sensor's or perception's run: woken as `wake` says, ending after `max_read_failures`
    /// failed device reads in a row, reading neither the emergency stop nor the operator's mode
    /// (it drives no actuator), until SIGINT/SIGTERM.
    pub fn sensor(wake: Wake, max_read_failures: u32) -> Self {
        WakeOptions {
            wake,
            runner: RunnerConfig {
                max_read_failures,
                mode_source: ModeSource::WithoutOperator,
            },
            obeys: false,
            stop: None,
        }
    }
}

/// Runs `node` with its `devices`, woken as `options.wake` says, until SIGINT/SIGTERM,
/// `options.stop` or an error. The devices are put in their safe state and the node's last
/// messages sent however the run ends. The summary is the number of ticks.
pub fn run_on_wake<N: Node>(
    context: &Context,
    node: N,
    devices: N::Devices,
    options: WakeOptions<'_>,
) -> Result<Finished<N, u64>, RunError> {
    let mut runner = Runner::new(node, devices, options.runner);
    let (inputs, outputs) = runner.slots_mut();
    let mut transport = IpcTransport::open_with(context, inputs, outputs, options.obeys)?;
    let mut health = HealthReporter::new(context)?;
    let stopped = || {
        options
            .stop
            .is_some_and(|stop| stop.load(Ordering::Relaxed))
    };
    tracing::info!(node = runner.node().name(), wake = ?options.wake, "running");
    let result = match options.wake {
        Wake::Input { topic } => {
            let port = transport
                .input_port(topic)
                .ok_or_else(|| RunError::NoSuchInput {
                    node: runner.node().name().to_owned(),
                    topic,
                })?;
            let waiter = Waiter::new()?;
            let input = port.attach(&waiter)?;
            let beat = waiter.attach_interval(HEARTBEAT_PERIOD)?;
            let heartbeat_ns = HEARTBEAT_PERIOD.as_nanos() as u64;
            let mut last_heartbeat_ns = MonotonicClock::read_ns();
            waiter
                .run(|attachment| -> Result<Flow, RunError> {
                    if attachment.has_event_from(&input) {
                        runner.tick(&mut transport, MonotonicClock::read_ns())?;
                        // More work: tick again at once; the wait set's interval is not seen
                        // meanwhile, so the heartbeat goes out here when due.
                        while runner.node().has_more_work() {
                            if harvest_ipc::termination::requested() || stopped() {
                                return Ok(Flow::Stop);
                            }
                            let now_ns = MonotonicClock::read_ns();
                            if now_ns.saturating_sub(last_heartbeat_ns) >= heartbeat_ns {
                                last_heartbeat_ns = now_ns;
                                heartbeat(&mut health, &mut runner, None)?;
                            }
                            runner.tick(&mut transport, now_ns)?;
                        }
                    }
                    if attachment.has_event_from(&beat) {
                        last_heartbeat_ns = MonotonicClock::read_ns();
                        heartbeat(&mut health, &mut runner, None)?;
                        if stopped() {
                            return Ok(Flow::Stop);
                        }
                    }
                    Ok(Flow::Continue)
                })
                .map(|_| runner.ticks())
                .map_err(harvest_ipc::RunError::flatten)
        }
        Wake::Device => {
            harvest_ipc::termination::install_handler()?;
            let heartbeat_ns = HEARTBEAT_PERIOD.as_nanos() as u64;
            let mut next_heartbeat_ns = MonotonicClock::read_ns();
            let mut run = || -> Result<u64, RunError> {
                while !harvest_ipc::termination::requested() && !stopped() {
                    let now_ns = MonotonicClock::read_ns();
                    runner.tick(&mut transport, now_ns)?;
                    if now_ns >= next_heartbeat_ns {
                        next_heartbeat_ns = now_ns + heartbeat_ns;
                        heartbeat(&mut health, &mut runner, None)?;
                    }
                }
                Ok(runner.ticks())
            };
            run()
        }
    };
    if let Err(error) = runner.shutdown(&mut transport, MonotonicClock::read_ns()) {
        tracing::warn!(%error, "last messages not sent");
    }
    Ok(Finished { runner, result })
}
