//! The soak's loop: start the stack, follow its processes and channels, act on the schedule,
//! sample, stop, report.

use super::error::SoakError;
use super::inputs::BadInputWriters;
use super::options::SoakArgs;
use super::procs;
use super::report::{
    CtlRecord, InputRecord, KillRecord, Outcome, PidChange, RestartCount, Sample, SoakReport,
    TruthFigures, growth_of, shm_of,
};
use super::schedule::{Action, BadInput, Expect, ScheduleSpec, Timed, make_schedule};
use super::stack::{SoakLaunch, SoakStack, StackSummary, free_port};
use harvest_ipc::catalogue::{HARVEST_EVENTS, PROCESS_HEALTH, SAFETY_VIOLATION, SIM_GROUND_TRUTH};
use harvest_ipc::payloads::{HarvestEventKind, TrueAppleState};
use harvest_ipc::{Context, Domain, MonotonicClock};
use harvest_supervisor::ViolationLog;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use rand::SeedableRng;
use rand::rngs::SmallRng;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

const TICK: Duration = Duration::from_millis(100);
const PID_SCAN_PERIOD: Duration = Duration::from_secs(1);
/// A `ctl` without an answer this soon after the soak killed the executive is explained.
const EXECUTIVE_RESTART_ALLOWANCE: Duration = Duration::from_secs(20);
/// Nothing new (replant) starts this close to the end.
const QUIET_END: Duration = Duration::from_secs(10);

/// Runs the soak; the report's verdicts say whether the stack held.
pub fn run_soak(args: &SoakArgs) -> Result<SoakReport, SoakError> {
    args.validate()?;
    let executable = match &args.harvest_exe {
        Some(path) => path.clone(),
        None => std::env::current_exe().map_err(|source| SoakError::File {
            path: PathBuf::from("/proc/self/exe"),
            source,
        })?,
    };
    let domain = harvest_ipc::ScratchDomain::new("soak");
    let scratch = std::env::temp_dir().join(format!("harvest-soak-{}", domain.name()));
    std::fs::create_dir_all(&scratch).map_err(|source| SoakError::File {
        path: scratch.clone(),
        source,
    })?;
    let launch = SoakLaunch::default_stack(free_port()?, free_port()?)?;
    let names = launch.process_names();
    let schedule = make_schedule(&ScheduleSpec {
        seed: args.seed,
        duration: args.duration,
        warmup: args.warmup,
        kill_every: args.kill_every,
        max_kills: args.max_kills,
        ctl_every: args.ctl_every,
        bad_input_every: args.bad_input_every,
        processes: names.clone(),
    });
    eprintln!(
        "harvest soak: {:?} in domain {} ({} scheduled actions), scratch {}",
        args.duration,
        domain.name(),
        schedule.len(),
        scratch.display()
    );
    let outcome = soak(
        args,
        &executable,
        &domain,
        &launch,
        &names,
        &schedule,
        &scratch,
    );
    // Whatever happened: the world state file of the domain, the scratch directory.
    let state_file = harvest_sim::world_state::default_state_path(&domain);
    let _ = std::fs::remove_file(&state_file);
    domain.remove_unused();
    if !args.keep_files {
        if let Err(error) = std::fs::remove_dir_all(&scratch) {
            tracing::warn!(path = %scratch.display(), %error, "scratch directory not removed");
        }
    } else {
        eprintln!("harvest soak: files kept in {}", scratch.display());
    }
    let report = outcome?;
    if let Some(path) = &args.out {
        let json = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, json).map_err(|source| SoakError::File {
            path: path.clone(),
            source,
        })?;
    }
    Ok(report)
}

/// What the loop gathers.
#[derive(Default)]
struct Gathered {
    samples: Vec<Sample>,
    kills: Vec<KillRecord>,
    pid_changes: Vec<PidChange>,
    ctl: Vec<CtlRecord>,
    bad_inputs: Vec<InputRecord>,
    replants_s: Vec<f64>,
    /// Recorder pid -> its last `dropped` figure.
    recorder_drops: BTreeMap<u32, u64>,
    /// Per world: max apples harvested, dropped.
    worlds: Vec<(u32, u32)>,
    /// `safety/violation` findings, each once (re-sent stop requests left out).
    violations: ViolationLog,
    /// `AttemptEnded` events on `harvest/events`: all, and those that harvested.
    attempts_ended: u32,
    harvested_events: u32,
    killed_pids: BTreeSet<u32>,
    executive_killed_at: Option<Instant>,
    stack_ended_early: Option<String>,
}

fn soak(
    args: &SoakArgs,
    executable: &Path,
    domain: &Domain,
    launch: &SoakLaunch,
    names: &[String],
    schedule: &[Timed],
    scratch: &Path,
) -> Result<SoakReport, SoakError> {
    let mut stack = SoakStack::start(executable, domain, launch, scratch, args.duration)?;
    let started = Instant::now();
    let supervisor_pid = stack.pid();
    let context = Context::new(domain, "soak")?;
    let health = context.subscriber_with_buffer(PROCESS_HEALTH, 256)?;
    let events = context.subscriber_with_buffer(HARVEST_EVENTS, 256)?;
    let violations = context.subscriber_with_buffer(SAFETY_VIOLATION, 256)?;
    let truth = context.subscriber(SIM_GROUND_TRUTH)?;
    let mut writers = BadInputWriters::open(&context);
    let mut rng = SmallRng::seed_from_u64(args.seed ^ 0x50a4);
    let mut g = Gathered {
        worlds: vec![(0, 0)],
        ..Gathered::default()
    };
    let mut current: BTreeMap<String, u32> = procs::stack_children(supervisor_pid);
    let mut next_action = 0usize;
    let mut last_scan = Instant::now();
    let mut next_sample = started;
    let mut replant_at: Option<Duration> = None;
    let mut world_since_ns = 0u64;
    loop {
        let elapsed = started.elapsed();
        if elapsed >= args.duration {
            break;
        }
        if let Err(error) = stack.check_running() {
            g.stack_ended_early = Some(error.to_string());
            break;
        }
        // Channels.
        let _ = health.drain(|beat| {
            if beat.process_name.as_str() == "recorder" && beat.detail.as_str() == "dropped" {
                g.recorder_drops.insert(beat.pid, beat.detail_value);
            }
        });
        let mut complete = false;
        let _ = events.drain(|event| match event.kind.get() {
            Ok(HarvestEventKind::HarvestComplete) => complete = true,
            Ok(HarvestEventKind::AttemptEnded) => {
                g.attempts_ended += 1;
                g.harvested_events += u32::from(event.harvested != 0);
            }
            _ => {}
        });
        let _ = violations.drain(|violation| {
            g.violations.record(violation);
        });
        let _ = truth.drain(|message| {
            let count = |state: TrueAppleState| {
                message
                    .apples
                    .iter()
                    .filter(|a| a.state.get() == Ok(state))
                    .count() as u32
            };
            // A world replaced by a replant still publishes until it is killed.
            let world = if message.header.publish_ns >= world_since_ns {
                g.worlds.len() - 1
            } else {
                g.worlds.len().saturating_sub(2)
            };
            let entry = &mut g.worlds[world];
            entry.0 = entry.0.max(count(TrueAppleState::Harvested));
            entry.1 = entry.1.max(count(TrueAppleState::Dropped));
        });
        if complete
            && !args.replant_after.is_zero()
            && replant_at.is_none()
            && elapsed + args.replant_after + QUIET_END < args.duration
        {
            replant_at = Some(elapsed + args.replant_after);
        }
        // Processes.
        if last_scan.elapsed() >= PID_SCAN_PERIOD {
            last_scan = Instant::now();
            scan(&mut g, &mut current, supervisor_pid, elapsed);
        }
        if Instant::now() >= next_sample {
            next_sample += args.sample_every;
            g.samples
                .push(sample(domain, supervisor_pid, &current, elapsed));
        }
        // Actions.
        if replant_at.is_some_and(|at| elapsed >= at) {
            replant_at = None;
            g.replants_s.push(elapsed.as_secs_f64());
            kill_process(&mut g, &current, "sim", "replant", elapsed);
            world_since_ns = MonotonicClock::read_ns();
            let state_file = harvest_sim::world_state::default_state_path(domain);
            if let Err(error) = std::fs::remove_file(&state_file) {
                tracing::warn!(path = %state_file.display(), %error, "world state file not removed");
            }
            g.worlds.push((0, 0));
            kill_process(&mut g, &current, "vacuum", "replant", elapsed);
            tracing::info!(
                at_s = elapsed.as_secs(),
                "replanted: sim and vacuum killed, world state removed"
            );
        }
        while let Some(timed) = schedule.get(next_action).filter(|t| t.at <= elapsed) {
            next_action += 1;
            match &timed.action {
                Action::Kill { process } => {
                    kill_process(&mut g, &current, process, "schedule", elapsed);
                }
                Action::Ctl {
                    args: ctl_args,
                    expect,
                } => {
                    let record = run_ctl(executable, domain, ctl_args, *expect, &g, elapsed);
                    g.ctl.push(record);
                }
                Action::BadInput { input } => {
                    let record = feed(
                        *input,
                        executable,
                        domain,
                        &mut writers,
                        &mut rng,
                        &g,
                        elapsed,
                    );
                    g.bad_inputs.push(record);
                }
            }
        }
        std::thread::sleep(TICK);
    }
    // A last look and sample before the stop.
    let elapsed = started.elapsed();
    scan(&mut g, &mut current, supervisor_pid, elapsed);
    g.samples
        .push(sample(domain, supervisor_pid, &current, elapsed));
    drop(writers);
    drop(health);
    drop(events);
    drop(violations);
    drop(truth);
    drop(context);
    let status = stack.stop();
    let stdout = std::fs::read_to_string(&stack.stdout_path).unwrap_or_default();
    let stderr = std::fs::read_to_string(&stack.log_path).unwrap_or_default();
    let summary = StackSummary::parse(&stdout, &stderr);
    let left_after_stop = harvest_ipc::cleanup::leftover_files(domain).len() as u64;
    let recordings_bytes = directory_bytes(&scratch.join("recordings"));
    let duration_s = elapsed.as_secs_f64();
    let half_s = duration_s / 2.0;
    let min_minutes = (duration_s / 4.0 / 60.0).max(0.2);
    let mut growth_names = vec!["supervisor".to_owned()];
    growth_names.extend(names.iter().cloned());
    let growth = growth_names
        .iter()
        .map(|name| growth_of(name, &g.samples, half_s, min_minutes))
        .collect();
    let restarts = names
        .iter()
        .map(|name| restart_count(name, &g, &summary))
        .collect();
    let mut report = SoakReport {
        domain: domain.name().to_owned(),
        seed: args.seed,
        duration_s,
        bounds: args.bounds(),
        console_port: launch.console_port,
        foxglove_port: launch.foxglove_port,
        shm: shm_of(&g.samples, half_s, left_after_stop),
        samples: g.samples,
        kills: g.kills,
        pid_changes: g.pid_changes,
        ctl: g.ctl,
        bad_inputs: g.bad_inputs,
        replants_s: g.replants_s,
        restarts,
        growth,
        recorder_drops: g.recorder_drops.values().sum(),
        recorder_instances: g.recorder_drops.len() as u32,
        truth: TruthFigures {
            worlds: g.worlds.len() as u32,
            harvested: g.worlds.iter().map(|w| w.0).sum(),
            dropped: g.worlds.iter().map(|w| w.1).sum(),
        },
        violations_seen: g.violations.lines().len() as u64,
        attempts_ended: g.attempts_ended,
        harvested_events: g.harvested_events,
        stack: summary,
        stack_exit: status.map_or("unknown".to_owned(), |s| s.to_string()),
        stack_ended_early: g.stack_ended_early,
        recordings_bytes,
        verdicts: Vec::new(),
    };
    report.judge();
    Ok(report)
}

/// Looks at the supervisor's children: a new pid for a name is a restart, explained when the
/// soak killed the old one.
fn scan(
    g: &mut Gathered,
    current: &mut BTreeMap<String, u32>,
    supervisor_pid: u32,
    elapsed: Duration,
) {
    let now = procs::stack_children(supervisor_pid);
    for (name, &pid) in &now {
        if let Some(&old) = current.get(name)
            && old != pid
        {
            let explained = g.killed_pids.contains(&old);
            if !explained {
                tracing::warn!(process = %name, old, pid, "restart the soak did not cause");
            }
            g.pid_changes.push(PidChange {
                t_s: elapsed.as_secs_f64(),
                process: name.clone(),
                old_pid: old,
                new_pid: pid,
                explained,
            });
        }
        for kill in g.kills.iter_mut() {
            if kill.process == *name
                && kill.restarted_pid.is_none()
                && kill.pid.is_some_and(|killed| killed != pid)
            {
                kill.restarted_pid = Some(pid);
                kill.restart_seen_after_s = Some(elapsed.as_secs_f64() - kill.t_s);
            }
        }
    }
    // A process between its exit and its restart keeps its last pid here.
    for (name, pid) in now {
        current.insert(name, pid);
    }
}

fn sample(
    domain: &Domain,
    supervisor_pid: u32,
    current: &BTreeMap<String, u32>,
    elapsed: Duration,
) -> Sample {
    let mut processes = BTreeMap::new();
    if let Some(figures) = procs::figures(supervisor_pid) {
        processes.insert("supervisor".to_owned(), figures);
    }
    for (name, &pid) in current {
        if let Some(figures) = procs::figures(pid) {
            processes.insert(name.clone(), figures);
        }
    }
    let files = harvest_ipc::cleanup::leftover_files(domain);
    let shm_bytes = files
        .iter()
        .filter_map(|f| std::fs::metadata(f).ok())
        .map(|m| m.len())
        .sum();
    Sample {
        t_s: elapsed.as_secs_f64(),
        processes,
        shm_entries: files.len() as u64,
        shm_bytes,
    }
}

fn kill_process(
    g: &mut Gathered,
    current: &BTreeMap<String, u32>,
    process: &str,
    reason: &'static str,
    elapsed: Duration,
) {
    let pid = current
        .get(process)
        .copied()
        .filter(|&pid| procs::exists(pid) && !g.killed_pids.contains(&pid));
    if let Some(pid) = pid {
        match kill(Pid::from_raw(pid as i32), Signal::SIGKILL) {
            Ok(()) => {
                g.killed_pids.insert(pid);
                tracing::info!(process, pid, reason, "SIGKILL");
                if process == "executive" {
                    g.executive_killed_at = Some(Instant::now());
                }
            }
            Err(error) => tracing::warn!(process, pid, %error, "kill failed"),
        }
    }
    g.kills.push(KillRecord {
        t_s: elapsed.as_secs_f64(),
        process: process.to_owned(),
        pid,
        reason,
        restarted_pid: None,
        restart_seen_after_s: None,
    });
}

fn run_ctl(
    executable: &Path,
    domain: &Domain,
    ctl_args: &[String],
    expect: Expect,
    g: &Gathered,
    elapsed: Duration,
) -> CtlRecord {
    let output = Command::new(executable)
        .arg("--domain")
        .arg(domain.name())
        .arg("ctl")
        .args(ctl_args)
        .env_remove(harvest_ipc::domain::DOMAIN_ENV)
        .output();
    let (exit_code, answer) = match output {
        Ok(output) => {
            let text = if output.stdout.is_empty() {
                output.stderr
            } else {
                output.stdout
            };
            let text = String::from_utf8_lossy(&text);
            (
                output.status.code(),
                text.lines().next().unwrap_or_default().to_owned(),
            )
        }
        Err(error) => (None, format!("cannot run ctl: {error}")),
    };
    let executive_restarting = g
        .executive_killed_at
        .is_some_and(|at| at.elapsed() < EXECUTIVE_RESTART_ALLOWANCE);
    let outcome = match (exit_code, expect) {
        (Some(0 | 1), Expect::Answer) | (Some(1), Expect::Refused) => Outcome::Ok,
        (Some(2), _) if executive_restarting => Outcome::NoAnswerExplained,
        _ => Outcome::Unexpected,
    };
    if outcome == Outcome::Unexpected {
        tracing::warn!(args = ?ctl_args, ?exit_code, %answer, "unexpected ctl outcome");
    }
    CtlRecord {
        t_s: elapsed.as_secs_f64(),
        args: ctl_args.to_vec(),
        expect,
        exit_code,
        answer,
        outcome,
    }
}

fn feed(
    input: BadInput,
    executable: &Path,
    domain: &Domain,
    writers: &mut BadInputWriters,
    rng: &mut SmallRng,
    g: &Gathered,
    elapsed: Duration,
) -> InputRecord {
    let ctl = |args: Vec<String>| {
        let record = run_ctl(executable, domain, &args, Expect::Refused, g, elapsed);
        (
            format!(
                "ctl {} -> exit {:?}: {}",
                args.join(" "),
                record.exit_code,
                record.answer
            ),
            record.outcome,
        )
    };
    let published = |result: Result<String, String>| match result {
        Ok(detail) => (detail, Outcome::Ok),
        Err(error) => (format!("not sent: {error}"), Outcome::Unexpected),
    };
    let (detail, outcome) = match input {
        BadInput::WrongToken => {
            let token: String = (0..32)
                .map(|_| char::from(b"0123456789abcdef"[rand::Rng::random_range(rng, 0..16)]))
                .collect();
            ctl(vec!["--token".into(), token, "pause".into()])
        }
        BadInput::JogPastLimits => ctl(["jog", "--arm", "1", "--joint", "d", "--delta", "5"]
            .map(String::from)
            .to_vec()),
        BadInput::GarbageOperatorCommand => published(writers.garbage_operator_command(rng)),
        BadInput::UnknownCommandCode => {
            let path = harvest_operator::token::token_path(domain.name());
            match harvest_operator::token::read_token_file(&path) {
                Ok(token) => published(writers.unknown_command_code(rng, token.as_str())),
                Err(error) => (format!("no token: {error}"), Outcome::Unexpected),
            }
        }
        BadInput::GarbageHarvestEvent => published(writers.garbage_harvest_event(rng)),
        BadInput::GarbageHeartbeat => published(writers.garbage_heartbeat(rng)),
        BadInput::SpoofedHeartbeat => {
            published(writers.spoofed_heartbeat("arm1", std::process::id()))
        }
    };
    InputRecord {
        t_s: elapsed.as_secs_f64(),
        input,
        detail,
        outcome,
    }
}

/// Restarts of `name`: the supervisor's count, split by the soak's kills that were followed by a
/// restart.
fn restart_count(name: &str, g: &Gathered, summary: &StackSummary) -> RestartCount {
    let observed = g.pid_changes.iter().filter(|c| c.process == name).count() as u32;
    let observed_unexplained = g
        .pid_changes
        .iter()
        .filter(|c| c.process == name && !c.explained)
        .count() as u32;
    let kills = g
        .kills
        .iter()
        .filter(|k| k.process == name && k.pid.is_some())
        .count() as u32;
    let restarts = summary.restarts_of(name).unwrap_or(observed);
    let explained = kills.min(restarts);
    RestartCount {
        process: name.to_owned(),
        restarts,
        explained,
        unexplained: (restarts - explained).max(observed_unexplained),
        last_exit: summary
            .processes
            .iter()
            .find(|p| p.name == name)
            .map_or("-".to_owned(), |p| p.last_exit.clone()),
    }
}

fn directory_bytes(path: &Path) -> u64 {
    let Ok(entries) = std::fs::read_dir(path) else {
        return 0;
    };
    entries
        .flatten()
        .filter_map(|e| e.metadata().ok())
        .filter(|m| m.is_file())
        .map(|m| m.len())
        .sum()
}
