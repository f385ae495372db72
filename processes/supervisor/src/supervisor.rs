//! `harvest up`: run the launch file's processes, keep them alive, stop them in order.
//!
//! The loop is one iceoryx2 wait set: heartbeats on the health channel wake it, and a 100 ms
//! housekeeping interval reaps children (`waitpid` without blocking), starts processes whose
//! backoff has elapsed, kills hung ones, and refreshes the status. Housekeeping is not a hot
//! path; the processes' own loops are event-driven.
//!
//! The harvest itself is followed on `harvest/events`: each event worth showing becomes a line
//! on stdout ([`harvest_log::HarvestLog`]), and the harvest summary (attempted,
//! harvested, success rate, first-attempt successes, cycle times) is part of the final
//! [`Summary`]. With [`UpOptions::until_harvested`] the stack stops once the vacuum supervisor
//! reports that nothing is left to pick.
//!
//! A process that fails for good (its restarts used up) stops the stack when it is critical
//! (`critical` in the launch file); a non-critical one stays FAILED in the status, the summary
//! names it, and the supervisor publishes its state ([`ProcessRunState::Failed`]) on
//! `system/health` every heartbeat period under the process's name, so the console's process
//! table shows it failed instead of merely silent. The stack goes on.

use crate::child;
use crate::domain_lock::{DomainLock, DomainLockError, STOPPING_STACK_WAIT};
use crate::launch::{Launch, ProcessSpec};
use crate::restart_tracker::{RestartDecision, RestartTracker};
use crate::scheduling::SchedulingOutcome;
use crate::status::{self, ProcessPhase, ProcessStatus};
use crate::violation_log::ViolationLog;
use harvest_ipc::catalogue::{HARVEST_EVENTS, PROCESS_HEALTH, SAFETY_VIOLATION};
use harvest_ipc::payloads::{DeviceErrorCode, ProcessHealth, ProcessRunState};
use harvest_ipc::{
    Context, Domain, FixedString, Flow, HEARTBEAT_PERIOD, MonotonicClock, Publisher, RunEnd, Waiter,
};
use harvest_log::{HarvestLog, HarvestLogSummary};
use nix::sys::signal::Signal;
use std::io::IsTerminal;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

const HOUSEKEEPING_PERIOD: Duration = Duration::from_millis(100);
const STATUS_PERIOD_TTY: Duration = Duration::from_secs(1);
const STATUS_PERIOD_LOG: Duration = Duration::from_secs(5);
/// A process that ran this long without failing starts its backoff from the beginning again.
const STABLE_AFTER: Duration = Duration::from_secs(10);

/// How `harvest up` was asked to run.
#[derive(Debug, Clone)]
pub struct UpOptions {
    pub launch: Launch,
    pub domain: Domain,
    /// Stop by itself after this long.
    pub duration: Option<Duration>,
    /// The `harvest` executable children are started from.
    pub executable: PathBuf,
    /// Stop once the vacuum supervisor reports the harvest complete (`HarvestComplete` on
    /// `harvest/events`).
    pub until_harvested: bool,
    /// Stop once the executive's stop-and-go cycle finished the row (`RowFinished` on
    /// `harvest/events`).
    pub until_row_done: bool,
}

/// How the run ended.
#[derive(Debug, Clone)]
pub struct Summary {
    pub processes: Vec<ProcessStatus>,
    /// Set when a critical process failed for good (the stack was stopped because of it).
    pub failure: Option<String>,
    /// Non-critical processes that failed for good while the stack went on, in words.
    pub non_critical_failures: Vec<String>,
    pub ended_by: String,
    pub leftover_files: Vec<PathBuf>,
    /// The harvest as `harvest/events` told it (None when no harvest event arrived).
    pub harvest: Option<HarvestLogSummary>,
    /// The safety monitor's violations (`safety/violation`), in words, in the order received.
    pub safety_violations: Vec<String>,
}

impl Summary {
    /// The harvest summary (what `harvest up` prints on stdout at the end), if any harvest
    /// event arrived.
    pub fn render_harvest(&self) -> Option<String> {
        self.harvest.as_ref().map(ToString::to_string)
    }

    /// The safety violations (what `harvest up` prints on stdout after the harvest summary).
    pub fn render_safety(&self) -> String {
        let mut out = format!("safety violations: {}\n", self.safety_violations.len());
        for line in &self.safety_violations {
            out.push_str(&format!("  VIOLATION {line}\n"));
        }
        out
    }

    /// The processes' final states (what `harvest up` prints on stderr at the end).
    pub fn render(&self) -> String {
        let mut out = format!("harvest up ended: {}\n", self.ended_by);
        for process in &self.processes {
            out.push_str(&format!(
                "  {:<12} {:<10} restarts {:<2} messages {:<8} last exit: {}{}{}{}\n",
                process.name,
                match &process.phase {
                    ProcessPhase::FailedForGood { .. } if process.critical => "FAILED",
                    ProcessPhase::FailedForGood { .. } => "FAILED:noncritical",
                    ProcessPhase::Finished => "finished",
                    _ => "stopped",
                },
                process.restarts,
                process.main_channel_count,
                process.last_exit.as_deref().unwrap_or("-"),
                if process.deadline_misses > 0 {
                    format!("  deadline misses {}", process.deadline_misses)
                } else {
                    String::new()
                },
                process
                    .device_error_label()
                    .map_or(String::new(), |label| format!("  {label}")),
                if process.scheduling.is_empty() {
                    String::new()
                } else {
                    format!("  [{}]", process.scheduling)
                },
            ));
        }
        for failure in &self.non_critical_failures {
            out.push_str(&format!("not critical, the stack went on: {failure}\n"));
        }
        if let Some(failure) = &self.failure {
            out.push_str(&format!("failure: {failure}\n"));
        }
        if !self.leftover_files.is_empty() {
            out.push_str(&format!(
                "warning: {} iceoryx2 files of this domain remain\n",
                self.leftover_files.len()
            ));
        }
        out
    }
}

/// Why the supervisor could not run at all.
#[derive(Debug, thiserror::Error)]
pub enum SupervisorError {
    /// Another stack runs in the domain (or its processes are still stopping).
    #[error(transparent)]
    DomainTaken(#[from] DomainLockError),
    #[error("supervisor node: {0}")]
    Node(#[from] harvest_ipc::error::NodeError),
    #[error("supervisor channel: {0}")]
    Channel(#[from] harvest_ipc::error::OpenChannelError),
    #[error("supervisor receiving harvest events: {0}")]
    Receive(#[from] harvest_ipc::error::ReceiveError),
    #[error("supervisor event loop: {0}")]
    Wait(#[from] harvest_ipc::error::WaitError),
    #[error("cleaning stale resources: {0}")]
    Cleanup(#[from] harvest_ipc::cleanup::CleanupError),
    #[error(transparent)]
    ControlToken(#[from] harvest_operator::token::TokenError),
}

/// The control token of this run: made at start, printed, written to the domain's
/// token file (mode 0600, `harvest_operator::token::token_path`) and handed to the children;
/// the file (and the executive's mode file beside it) is removed when the stack stops.
struct ControlTokenFile {
    token: harvest_operator::ControlToken,
    path: PathBuf,
}

impl ControlTokenFile {
    fn create(domain: &Domain) -> Result<Self, SupervisorError> {
        use harvest_operator::token;
        let control = Self {
            token: harvest_operator::ControlToken::generate()?,
            path: token::token_path(domain.name()),
        };
        token::write_token_file(&control.path, &control.token)?;
        eprintln!(
            "control token: {} (in {}; `harvest ctl` reads it from there)",
            control.token.as_str(),
            control.path.display()
        );
        Ok(control)
    }
}

impl Drop for ControlTokenFile {
    fn drop(&mut self) {
        for path in [
            self.path.clone(),
            harvest_operator::mode_file::mode_path(&self.path),
        ] {
            if let Err(error) = std::fs::remove_file(&path)
                && error.kind() != std::io::ErrorKind::NotFound
            {
                tracing::warn!(path = %path.display(), %error, "could not remove");
            }
        }
    }
}

struct Managed {
    spec: ProcessSpec,
    child: Option<Child>,
    started_at: Instant,
    last_heartbeat: Option<Instant>,
    tracker: RestartTracker,
    status: ProcessStatus,
    count_at_last_status: u64,
    /// What the current instance's scheduling settings became.
    scheduling: SchedulingOutcome,
    /// The pid of the latest instance (0 before the first start).
    last_pid: u32,
}

impl Managed {
    /// The scheduling label for the status: what the kernel granted at the start, and for a
    /// memory lock (taken by the process itself before its loop) the kernel's `VmLck` once the
    /// process reports (refused or not done: `mlock:none`).
    fn scheduling_label(&self) -> String {
        let mut label = self.scheduling.label();
        if self.scheduling.asked.lock_memory
            && let Some(child) = &self.child
            && self.last_heartbeat.is_some()
        {
            let locked_kib = harvest_ipc::memory_lock::locked_kib(child.id()).unwrap_or(0);
            let shown = if locked_kib > 0 {
                format!("mlock {}MiB", locked_kib.div_ceil(1024))
            } else {
                "mlock:none".to_owned()
            };
            label = label.replace("mlock", &shown);
        }
        label
    }
}

/// Runs the stack until a signal, `--duration`, or a process failing for good. Refuses to start
/// when a stack already runs in the domain ([`DomainLock`], taken before anything else and held
/// until the stack is stopped).
pub fn run(options: UpOptions) -> Result<Summary, SupervisorError> {
    let domain = &options.domain;
    let domain_lock = DomainLock::acquire(domain, STOPPING_STACK_WAIT)?;
    tracing::debug!(path = %domain_lock.file_path().display(), "domain lock taken");
    // Only now: no other stack runs in the domain. (The cleanup removes dead nodes only, but
    // nothing of this stack may start while another one might.)
    let alive_nodes = clean_dead_nodes(domain)?;
    if alive_nodes > 0 {
        tracing::warn!(
            domain = %domain,
            alive_nodes,
            "processes outside any stack are already in the domain (started by hand?): a channel \
        with one writer refuses this stack's process if one of them writes it"
        );
    }
    let control = ControlTokenFile::create(domain)?;
    let context = Context::new(domain, "supervisor")?;
    let health = context.subscriber_with_buffer(PROCESS_HEALTH, 256)?;
    let waiter = Waiter::new()?;
    let health_guard = waiter.attach_listener(health.listener())?;
    let tick_guard = waiter.attach_interval(HOUSEKEEPING_PERIOD)?;
    let events = context.subscriber_with_buffer(HARVEST_EVENTS, 256)?;
    let events_guard = waiter.attach_listener(events.listener())?;
    let violations = context.subscriber_with_buffer(SAFETY_VIOLATION, 256)?;
    let violations_guard = waiter.attach_listener(violations.listener())?;
    let mut failed_health = context.publisher(PROCESS_HEALTH)?;
    let failed_health_guard = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let mut safety_violations = ViolationLog::default();
    let mut harvest_log = HarvestLog::new(MonotonicClock::read_ns());
    let mut harvest_events = 0u64;

    let stack = options.launch.stack;
    let started = Instant::now();
    let mut processes: Vec<Managed> = options
        .launch
        .processes
        .iter()
        .map(|spec| Managed {
            spec: spec.clone(),
            child: None,
            started_at: started,
            last_heartbeat: None,
            tracker: RestartTracker::new(spec),
            status: ProcessStatus {
                name: spec.name.clone(),
                phase: ProcessPhase::WaitingToRestart { until: started },
                restarts: 0,
                last_exit: None,
                main_channel_count: 0,
                main_channel_rate_hz: 0.0,
                detail: String::new(),
                detail_value: 0,
                deadline_misses: 0,
                scheduling: String::new(),
                run_state: None,
                critical: spec.critical,
                last_device_error: DeviceErrorCode::None,
            },
            count_at_last_status: 0,
            scheduling: SchedulingOutcome::none(),
            last_pid: 0,
        })
        .collect();
    tracing::info!(
        domain = %domain,
        launch = %options.launch.source,
        processes = processes.len(),
        "starting the stack"
    );

    let tty = std::io::stderr().is_terminal();
    let status_period = if tty {
        STATUS_PERIOD_TTY
    } else {
        STATUS_PERIOD_LOG
    };
    let mut last_status = started;
    let mut status_lines = 0usize;
    let mut failure: Option<String> = None;
    let mut ended_by = String::from("signal");
    let hang_timeout = Duration::from_millis(stack.hang_timeout_ms);
    let startup_grace = Duration::from_millis(stack.startup_grace_ms);

    let run_end = waiter.run(|attachment| -> Result<Flow, SupervisorError> {
        let now = Instant::now();
        if attachment.has_event_from(&failed_health_guard) {
            publish_failed(&mut failed_health, &processes);
        }
        if attachment.has_event_from(&violations_guard) {
            violations.drain(|violation| {
                if let Some(line) = safety_violations.record(violation) {
                    tracing::error!(violation = %line, "safety violation");
                }
            })?;
        }
        if attachment.has_event_from(&events_guard) {
            let mut lines = Vec::new();
            events.drain(|event| {
                harvest_events += 1;
                if let Some(line) = harvest_log.on_event(event) {
                    lines.push(line);
                }
            })?;
            if !lines.is_empty() {
                if tty && status_lines > 0 {
                    // Clear the in-place status block; it is drawn again below the lines.
                    eprint!("\x1b[{status_lines}A\x1b[J");
                    status_lines = 0;
                }
                let mut stdout = std::io::stdout().lock();
                for line in &lines {
                    let _ = writeln!(stdout, "{line}");
                }
                let _ = stdout.flush();
            }
            if options.until_harvested && harvest_log.complete() {
                ended_by = "harvest complete".to_owned();
                return Ok(Flow::Stop);
            }
            if options.until_row_done && harvest_log.row_done() {
                ended_by = "row done".to_owned();
                return Ok(Flow::Stop);
            }
        }
        if attachment.has_event_from(&health_guard) {
            // A heartbeat that cannot be received (a crashed publisher's memory) is a missed
            // beat: the hang timeout judges it, the supervisor goes on.
            let drained = health.drain(|beat| {
                let name = beat.process_name.as_str();
                // Only the current instance's beats count (not a killed predecessor's).
                if let Some(process) = processes.iter_mut().find(|p| {
                    p.spec.name == name && p.child.as_ref().map(|c| c.id()) == Some(beat.pid)
                }) {
                    process.last_heartbeat = Some(now);
                    process.status.main_channel_count = beat.main_channel_count;
                    process.status.detail = beat.detail.as_str().to_owned();
                    process.status.detail_value = beat.detail_value;
                    process.status.deadline_misses = beat.deadline_misses;
                    let device_error = beat.last_device_error.get().unwrap_or(DeviceErrorCode::Other);
                    if device_error != DeviceErrorCode::None
                        && device_error != process.status.last_device_error
                    {
                        tracing::warn!(process = %process.spec.name, kind = %device_error, "process reports a device error");
                    }
                    if device_error != DeviceErrorCode::None {
                        process.status.last_device_error = device_error;
                    }
                    let run_state = beat.run_state.get().ok();
                    if run_state != process.status.run_state {
                        if run_state == Some(ProcessRunState::Degraded) {
                            tracing::warn!(process = %process.spec.name, detail = %process.status.detail, value = beat.detail_value, "process reports itself degraded");
                        } else if process.status.run_state == Some(ProcessRunState::Degraded) {
                            tracing::info!(process = %process.spec.name, "process no longer degraded");
                        }
                    }
                    process.status.run_state = run_state;
                }
            });
            if let Err(error) = drained {
                tracing::debug!(%error, "heartbeats not received");
            }
        }
        if !attachment.has_event_from(&tick_guard) {
            return Ok(Flow::Continue);
        }
        for process in processes.iter_mut() {
            match process.status.phase.clone() {
                ProcessPhase::WaitingToRestart { until } if now >= until => {
                    start(process, &options, &domain_lock, control.token.as_str(), now);
                }
                ProcessPhase::Running { .. } => {
                    let exited = process
                        .child
                        .as_mut()
                        .and_then(|child| child.try_wait().ok().flatten());
                    if let Some(exit_status) = exited {
                        process.child = None;
                        let failed = !exit_status.success();
                        on_exit(process, describe_exit(exit_status), failed, now, domain);
                    } else if is_hung(process, now, hang_timeout, startup_grace) {
                        tracing::warn!(
                            process = %process.spec.name,
                            timeout_ms = stack.hang_timeout_ms,
                            "no heartbeat: killing hung process"
                        );
                        if let Some(mut child) = process.child.take() {
                            child::signal_group(&child, Signal::SIGKILL);
                            let _ = child.wait();
                        }
                        let reason = format!(
                            "hung (no heartbeat for {} ms), killed",
                            stack.hang_timeout_ms
                        );
                        on_exit(process, reason, true, now, domain);
                    } else if now.duration_since(process.started_at) > STABLE_AFTER {
                        process.tracker.mark_stable();
                    }
                }
                _ => {}
            }
            if let ProcessPhase::FailedForGood { reason } = &process.status.phase
                && process.spec.critical
            {
                failure = Some(format!(
                    "process {:?} failed for good: {reason}",
                    process.spec.name
                ));
                ended_by = "a critical process failed for good".to_owned();
                return Ok(Flow::Stop);
            }
        }
        let failed_non_critical =
            |p: &Managed| matches!(p.status.phase, ProcessPhase::FailedForGood { .. });
        if processes
            .iter()
            .all(|p| p.status.phase == ProcessPhase::Finished || failed_non_critical(p))
        {
            ended_by = if processes.iter().any(failed_non_critical) {
                "every process finished or failed for good (none critical)".to_owned()
            } else {
                "all processes finished".to_owned()
            };
            return Ok(Flow::Stop);
        }
        if now.duration_since(last_status) >= status_period {
            let interval_s = now.duration_since(last_status).as_secs_f64();
            for process in processes.iter_mut() {
                let count = process.status.main_channel_count;
                process.status.main_channel_rate_hz =
                    count.saturating_sub(process.count_at_last_status) as f64 / interval_s;
                process.count_at_last_status = count;
                process.status.scheduling = process.scheduling_label();
            }
            last_status = now;
            let statuses: Vec<ProcessStatus> = processes.iter().map(|p| p.status.clone()).collect();
            let text = status::render(&statuses, now.duration_since(started).as_secs_f64());
            if tty {
                if status_lines > 0 {
                    // Move up over the previous block and clear it: a live, in-place status.
                    eprint!("\x1b[{status_lines}A\x1b[J");
                }
                status_lines = text.lines().count();
                eprint!("{text}");
            } else {
                eprint!("{text}");
            }
        }
        if let Some(duration) = options.duration
            && now.duration_since(started) >= duration
        {
            ended_by = format!("--duration {}s elapsed", duration.as_secs_f64());
            return Ok(Flow::Stop);
        }
        Ok(Flow::Continue)
    });
    let run_error = match run_end {
        Ok(RunEnd::Signal) => {
            ended_by = "SIGINT/SIGTERM".to_owned();
            None
        }
        Ok(RunEnd::Stopped) => None,
        Err(error) => Some(error.flatten()),
    };
    drop(health_guard);
    drop(failed_health_guard);
    drop(tick_guard);
    drop(events_guard);
    drop(violations_guard);
    let drained = violations.drain(|violation| {
        safety_violations.record(violation);
    });
    if let Err(error) = drained {
        tracing::debug!(%error, "safety violations sent while stopping not received");
    }
    drop(violations);
    // Events sent while the stack stops (attempts cut short) still count.
    let drained = events.drain(|event| {
        harvest_events += 1;
        if let Some(line) = harvest_log.on_event(event) {
            println!("{line}");
        }
    });
    if let Err(error) = drained {
        tracing::debug!(%error, "harvest events sent while stopping not received");
    }
    drop(events);
    // The summary shows the scheduling as granted (and the memory lock) while the children run.
    for process in processes.iter_mut() {
        process.status.scheduling = process.scheduling_label();
    }
    shutdown(
        &mut processes,
        Duration::from_millis(stack.shutdown_grace_ms),
    );
    drop(health);
    drop(context);
    drop(control);
    if clean_dead_nodes(domain)? == 0 {
        // Nothing of the domain runs: its node registry, the one file iceoryx2 would keep in
        // /dev/shm for good, goes too (a node still there, e.g. a `harvest ctl`, keeps it).
        match harvest_ipc::cleanup::remove_unused_registry(domain) {
            Ok(removal) => tracing::debug!(?removal, "domain's node registry"),
            Err(error) => tracing::warn!(%error, "the domain's node registry is left in /dev/shm"),
        }
    }
    if let Some(error) = run_error {
        return Err(error);
    }
    let non_critical_failures = processes
        .iter()
        .filter_map(|p| match &p.status.phase {
            ProcessPhase::FailedForGood { reason } if !p.spec.critical => Some(format!(
                "process {:?} failed for good: {reason}",
                p.spec.name
            )),
            _ => None,
        })
        .collect();
    drop(failed_health);
    let summary = Summary {
        processes: processes.into_iter().map(|p| p.status).collect(),
        failure,
        non_critical_failures,
        ended_by,
        leftover_files: harvest_ipc::cleanup::leftover_files(domain),
        harvest: (harvest_events > 0).then(|| harvest_log.summary()),
        safety_violations: safety_violations.into_lines(),
    };
    // Every process of the stack is stopped: the domain is free for the next `harvest up`.
    drop(domain_lock);
    Ok(summary)
}

fn start(
    process: &mut Managed,
    options: &UpOptions,
    domain_lock: &DomainLock,
    control_token: &str,
    now: Instant,
) {
    match child::spawn(
        &options.executable,
        &process.spec,
        &options.domain,
        domain_lock.inheritable_fd(),
        control_token,
    ) {
        Ok((child, scheduling)) => {
            if scheduling.asked.is_default() {
                tracing::info!(process = %process.spec.name, pid = child.id(), "started");
            } else {
                let refusals = scheduling.refusals();
                tracing::info!(process = %process.spec.name, pid = child.id(),
                    scheduling = %scheduling.asked, granted = %scheduling.label(), "started");
                for refusal in &refusals {
                    tracing::warn!(process = %process.spec.name, "{refusal}");
                }
            }
            process.status.scheduling = scheduling.label();
            process.scheduling = scheduling;
            process.status.phase = ProcessPhase::Running { pid: child.id() };
            process.last_pid = child.id();
            process.child = Some(child);
            process.started_at = now;
            process.last_heartbeat = None;
            process.status.run_state = None;
        }
        Err(error) => {
            let reason = format!("cannot start {:?}: {error}", options.executable);
            on_exit(process, reason, true, now, &options.domain);
        }
    }
}

fn on_exit(process: &mut Managed, reason: String, failed: bool, now: Instant, domain: &Domain) {
    if failed {
        tracing::warn!(process = %process.spec.name, %reason, "process exited");
        // A crashed process leaves its iceoryx2 node behind: remove it before the restart.
        if let Err(error) = clean_dead_nodes(domain) {
            tracing::warn!(%error, "stale resource cleanup failed");
        }
    } else {
        tracing::info!(process = %process.spec.name, %reason, "process exited");
    }
    process.status.last_exit = Some(reason.clone());
    process.status.phase = match process.tracker.on_exit(now, failed) {
        RestartDecision::RestartAt(until) => {
            tracing::info!(process = %process.spec.name, backoff_ms = until.duration_since(now).as_millis() as u64, "restarting");
            ProcessPhase::WaitingToRestart { until }
        }
        RestartDecision::Finished => ProcessPhase::Finished,
        RestartDecision::FailedForGood => {
            if process.spec.critical {
                tracing::error!(process = %process.spec.name, %reason, "critical process failed for good: stopping the stack");
            } else {
                tracing::error!(process = %process.spec.name, %reason,
                    "process failed for good; it is not critical: the stack goes on without it");
            }
            ProcessPhase::FailedForGood { reason }
        }
    };
    process.status.restarts = process.tracker.restarts();
}

/// Publishes, under each non-critical process that failed for good, its state on
/// `system/health` (the console shows it; the process itself can no longer say it).
fn publish_failed(publisher: &mut Publisher<ProcessHealth>, processes: &[Managed]) {
    for process in processes {
        if !matches!(process.status.phase, ProcessPhase::FailedForGood { .. }) {
            continue;
        }
        let sent = publisher.publish_with(MonotonicClock::read_ns(), |health| {
            health.process_name = FixedString::new(&process.spec.name);
            health.pid = process.last_pid;
            health.run_state.set(ProcessRunState::Failed);
            // The kind of the last device error the process reported before it failed.
            health
                .last_device_error
                .set(process.status.last_device_error);
            health._reserved = [0; 2];
            health.main_channel_count = process.status.main_channel_count;
            health.detail_value = u64::from(process.status.restarts);
            health.detail = FixedString::new("failed for good, restarts");
            health.deadline_misses = process.status.deadline_misses;
        });
        if let Err(error) = sent {
            tracing::debug!(%error, process = %process.spec.name, "failed state not published");
        }
    }
}

fn is_hung(
    process: &Managed,
    now: Instant,
    hang_timeout: Duration,
    startup_grace: Duration,
) -> bool {
    match process.last_heartbeat {
        Some(beat) => now.duration_since(beat) > hang_timeout,
        None => now.duration_since(process.started_at) > startup_grace.max(hang_timeout),
    }
}

fn describe_exit(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(code), _) => format!("exit code {code}"),
        (None, Some(signal)) => {
            let name = Signal::try_from(signal)
                .map(|s| s.as_str())
                .unwrap_or("unknown signal");
            format!("killed by {name}")
        }
        _ => "unknown exit".to_owned(),
    }
}

/// SIGTERM to each process in reverse start order, waiting up to `grace` for each, then SIGKILL.
fn shutdown(processes: &mut [Managed], grace: Duration) {
    for process in processes.iter_mut().rev() {
        let Some(mut child) = process.child.take() else {
            continue;
        };
        tracing::info!(process = %process.spec.name, pid = child.id(), "stopping");
        child::signal_group(&child, Signal::SIGTERM);
        let deadline = Instant::now() + grace;
        let exit = loop {
            match child.try_wait() {
                Ok(Some(status)) => break Some(status),
                Ok(None) if Instant::now() < deadline => {
                    // Shutdown only: a short bounded wait between checks of one exiting child.
                    std::thread::sleep(Duration::from_millis(10));
                }
                _ => break None,
            }
        };
        let exit = match exit {
            Some(status) => describe_exit(status),
            None => {
                tracing::warn!(process = %process.spec.name, grace_ms = grace.as_millis() as u64, "did not stop in time: SIGKILL");
                child::signal_group(&child, Signal::SIGKILL);
                child
                    .wait()
                    .map(describe_exit)
                    .unwrap_or_else(|error| format!("wait failed: {error}"))
            }
        };
        process.status.last_exit = Some(exit);
        if !matches!(process.status.phase, ProcessPhase::FailedForGood { .. }) {
            process.status.phase = ProcessPhase::Stopped;
        }
    }
}

/// Removes the resources of the domain's dead nodes; returns how many nodes are alive.
fn clean_dead_nodes(domain: &Domain) -> Result<usize, SupervisorError> {
    let report = harvest_ipc::cleanup::remove_dead_nodes(domain)?;
    if !report.removed_nodes.is_empty() {
        tracing::info!(nodes = ?report.removed_nodes, "removed stale iceoryx2 resources of dead nodes");
    }
    for (node, reason) in &report.failed_nodes {
        tracing::warn!(%node, %reason, "could not remove stale resources");
    }
    Ok(report.alive_nodes)
}
