//! `harvest monitor`: the monitored channels of a running stack, judged as they arrive. Each
//! channel's subscriber is attached to the wait set, so the monitor sleeps until a message
//! comes (no polling); a 100 ms interval only ends the run after `--duration`. Messages are
//! stamped with the monotonic clock when taken from the queue.

use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, VACUUM_STATE};
use harvest_ipc::payloads::EmergencyStop;
use harvest_ipc::{
    Context, Domain, FixedString, Flow, MonotonicClock, Payload, Subscriber, Waiter,
};
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::{MonitorConfig, Violation};

use crate::error::MonitorError;
use crate::mapping::MappingConfig;
use crate::stack_monitor::{MonitorReport, StackMessage, StackMonitor};

/// How often the loop wakes without traffic to check the duration and the stop time.
const HOUSEKEEPING: Duration = Duration::from_millis(20);

fn subscribe<T: Payload>(
    context: &Context,
    channel: harvest_ipc::Channel<T>,
) -> Result<Subscriber<T>, MonitorError> {
    // The largest buffer: every transition matters, not only the latest state.
    context
        .subscriber_with_buffer(channel, usize::MAX)
        .map_err(|error| MonitorError::Channels(error.to_string()))
}

/// Monitors the stack of `domain` until `duration` has passed (or a termination signal);
/// `on_violation` sees each violation when it is found. With `engage_stop_after`, the monitor
/// also engages `safety/emergency_stop` itself that long after it started (and leaves it
/// engaged), to measure the stack's reaction live ([`crate::stack_monitor::StopReaction`]).
pub fn run_live(
    domain: &Domain,
    process_name: &str,
    duration: Option<Duration>,
    engage_stop_after: Option<Duration>,
    mapping: MappingConfig,
    checks: MonitorConfig,
    mut on_violation: impl FnMut(&Violation),
) -> Result<MonitorReport, MonitorError> {
    let context = Context::new(domain, process_name)
        .map_err(|error| MonitorError::Channels(error.to_string()))?;
    let vacuum = subscribe(&context, VACUUM_STATE)?;
    let commands = [
        subscribe(&context, ARM_COMMAND[0])?,
        subscribe(&context, ARM_COMMAND[1])?,
    ];
    let states = [
        subscribe(&context, ARM_STATE[0])?,
        subscribe(&context, ARM_STATE[1])?,
    ];
    let stop = subscribe(&context, EMERGENCY_STOP)?;
    let mut stop_publisher = match engage_stop_after {
        Some(_) => Some(
            context
                .publisher(EMERGENCY_STOP)
                .map_err(|error| MonitorError::Channels(error.to_string()))?,
        ),
        None => None,
    };
    let waiter = Waiter::new()?;
    let _guards = [
        waiter.attach_listener(vacuum.listener())?,
        waiter.attach_listener(commands[0].listener())?,
        waiter.attach_listener(commands[1].listener())?,
        waiter.attach_listener(states[0].listener())?,
        waiter.attach_listener(states[1].listener())?,
        waiter.attach_listener(stop.listener())?,
    ];
    let _tick = waiter.attach_interval(HOUSEKEEPING)?;
    let started = Instant::now();
    let mut monitor = StackMonitor::new(mapping, checks);
    tracing::info!(%domain, ?duration, "safety monitor running");
    let mut judge = |monitor: &mut StackMonitor, message: StackMessage<'_>| {
        let found = monitor
            .feed(MonotonicClock::read_ns(), message)
            .map_err(|error| MonitorError::Channels(format!("trace: {error}")))?;
        found.iter().for_each(&mut on_violation);
        Ok::<(), MonitorError>(())
    };
    let end = waiter.run(|_attachment| -> Result<Flow, MonitorError> {
        if let (Some(after), Some(publisher)) = (engage_stop_after, stop_publisher.as_mut())
            && started.elapsed() >= after
        {
            let message = EmergencyStop {
                engaged: 1,
                reason: FixedString::new("harvest monitor: reaction measurement"),
                ..EmergencyStop::default()
            };
            publisher
                .publish(&message)
                .map_err(|error| MonitorError::Channels(error.to_string()))?;
            tracing::warn!("emergency stop engaged by the monitor (reaction measurement)");
            stop_publisher = None;
        }
        // Any wake-up: drain every queue (a wake-up may stand for several channels).
        while let Some(sample) = vacuum.receive()? {
            judge(&mut monitor, StackMessage::Vacuum(&sample))?;
        }
        for arm in ArmId::ALL {
            while let Some(sample) = commands[arm.index()].receive()? {
                judge(&mut monitor, StackMessage::Command(arm, &sample))?;
            }
            while let Some(sample) = states[arm.index()].receive()? {
                judge(&mut monitor, StackMessage::State(arm, &sample))?;
            }
        }
        while let Some(sample) = stop.receive()? {
            judge(&mut monitor, StackMessage::Stop(&sample))?;
        }
        Ok(if duration.is_some_and(|d| started.elapsed() >= d) {
            Flow::Stop
        } else {
            Flow::Continue
        })
    });
    if let Err(error) = end {
        return Err(error.flatten());
    }
    let dropped: u64 = [vacuum.dropped_count(), stop.dropped_count()]
        .into_iter()
        .chain(commands.iter().map(Subscriber::dropped_count))
        .chain(states.iter().map(Subscriber::dropped_count))
        .sum();
    if dropped > 0 {
        tracing::warn!(dropped, "messages lost before the monitor read them");
    }
    let before = monitor.violations().len();
    let report = monitor.finish(MonotonicClock::read_ns());
    report.violations[before..].iter().for_each(on_violation);
    Ok(report)
}
