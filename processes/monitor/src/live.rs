//! `harvest monitor`: the monitored channels of a running stack, judged as they arrive. Each
//! channel's subscriber is attached to the wait set, so the monitor sleeps until a message
//! comes (no polling); a 100 ms interval only ends the run after `--duration`. Messages are
//! stamped with the monotonic clock when taken from the queue.
//!
//! In the stack (`--on-violation report|stop`, the default launch file) each violation is also
//! published on `safety/violation` as soon as it is found, with the action the monitor asks
//! for: the executive engages the protective stop for `stop`. The monitor never writes
//! `safety/emergency_stop` itself (the executive is its one writer) and cannot release it; an
//! unanswered stop request is sent again until the stop is seen engaged
//! ([`crate::violation_outlet`]). A heartbeat on `system/health` lets the supervisor see it is alive.

use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, SAFETY_VIOLATION, VACUUM_STATE,
};
use harvest_ipc::payloads::{EmergencyStop, ProcessRunState};
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Payload, Subscriber,
    Waiter,
};
use harvest_robot_model::ArmId;
use harvest_safety::safety_monitor::{MonitorConfig, Violation};

use crate::error::MonitorError;
use crate::mapping::MappingConfig;
use crate::stack_monitor::{MonitorReport, StackMessage, StackMonitor};
use crate::violation_message::OnViolation;
use crate::violation_outlet::ViolationOutlet;

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

/// What the live monitor does besides judging.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LiveOptions {
    /// Stop after this long (else at a termination signal).
    pub duration: Option<Duration>,
    /// Ask the executive for the stop this long after starting (and leave it engaged), to
    /// measure the stack's reaction live ([`crate::stack_monitor::StopReaction`]).
    pub engage_stop_after: Option<Duration>,
    /// What to do with each violation besides printing it.
    pub on_violation: OnViolation,
}

/// Judges every queued `safety/emergency_stop` message and tells the outlet the stop's state.
fn judge_stop_messages(
    stop: &Subscriber<EmergencyStop>,
    monitor: &mut StackMonitor,
    outlet: &mut Option<ViolationOutlet>,
    judge: &mut impl FnMut(
        &mut StackMonitor,
        &mut Option<ViolationOutlet>,
        StackMessage<'_>,
    ) -> Result<(), MonitorError>,
) -> Result<(), MonitorError> {
    while let Some(sample) = stop.receive()? {
        if let Some(outlet) = outlet.as_mut() {
            outlet.stop_seen(sample.engaged != 0);
        }
        judge(monitor, outlet, StackMessage::Stop(&sample))?;
    }
    Ok(())
}

/// Monitors the stack of `domain` ([`LiveOptions`]); `print` sees each violation when it is
/// found.
pub fn run_live(
    domain: &Domain,
    process_name: &str,
    options: LiveOptions,
    mapping: MappingConfig,
    checks: MonitorConfig,
    mut print: impl FnMut(&Violation),
) -> Result<MonitorReport, MonitorError> {
    let LiveOptions {
        duration,
        engage_stop_after,
        on_violation,
    } = options;
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
    // The one writer of `safety/violation` (a second monitor publishing beside the stack's is
    // refused at port creation, naming the channel).
    let mut outlet = if on_violation.action().is_some() || engage_stop_after.is_some() {
        let publisher = context
            .publisher(SAFETY_VIOLATION)
            .map_err(|error| MonitorError::Channels(error.to_string()))?;
        Some(ViolationOutlet::new(publisher, on_violation.action()))
    } else {
        None
    };
    let mut health =
        HealthReporter::new(&context).map_err(|error| MonitorError::Channels(error.to_string()))?;
    let mut measurement_requested = false;
    let mut last_heartbeat: Option<Instant> = None;
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
    let mut judge = |monitor: &mut StackMonitor,
                     outlet: &mut Option<ViolationOutlet>,
                     message: StackMessage<'_>| {
        let found = monitor
            .feed(MonotonicClock::read_ns(), message)
            .map_err(|error| MonitorError::Channels(format!("trace: {error}")))?;
        for violation in found {
            print(violation);
            if let Some(outlet) = outlet.as_mut() {
                outlet.violation(violation)?;
            }
        }
        Ok::<(), MonitorError>(())
    };
    let end = waiter.run(|_attachment| -> Result<Flow, MonitorError> {
        if last_heartbeat.is_none_or(|at| at.elapsed() >= HEARTBEAT_PERIOD) {
            last_heartbeat = Some(Instant::now());
            let published = outlet.as_ref().map_or(0, ViolationOutlet::published);
            health
                .report(ProcessRunState::Running, published, "violations", published)
                .map_err(|error| MonitorError::Channels(error.to_string()))?;
        }
        if let (Some(after), Some(outlet)) = (engage_stop_after, outlet.as_mut())
            && !measurement_requested
            && started.elapsed() >= after
        {
            outlet.measurement_stop()?;
            measurement_requested = true;
        }
        // Any wake-up: drain every queue (a wake-up may stand for several channels). The
        // emergency stop's queue is read before each other message is judged: a message in
        // another queue that was sent after a change of the stop (an arm moving again after a
        // release) finds that change already queued, so it is judged in the right order.
        judge_stop_messages(&stop, &mut monitor, &mut outlet, &mut judge)?;
        while let Some(sample) = vacuum.receive()? {
            judge_stop_messages(&stop, &mut monitor, &mut outlet, &mut judge)?;
            judge(&mut monitor, &mut outlet, StackMessage::Vacuum(&sample))?;
        }
        for arm in ArmId::ALL {
            while let Some(sample) = commands[arm.index()].receive()? {
                judge_stop_messages(&stop, &mut monitor, &mut outlet, &mut judge)?;
                judge(
                    &mut monitor,
                    &mut outlet,
                    StackMessage::Command(arm, &sample),
                )?;
            }
            while let Some(sample) = states[arm.index()].receive()? {
                judge_stop_messages(&stop, &mut monitor, &mut outlet, &mut judge)?;
                judge(&mut monitor, &mut outlet, StackMessage::State(arm, &sample))?;
            }
        }
        if let Some(outlet) = outlet.as_mut() {
            outlet.retry()?;
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
    report.violations[before..].iter().for_each(print);
    Ok(report)
}
