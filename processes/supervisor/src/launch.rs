//! The launch file: which processes `harvest up` runs, with their restart policies.
//!
//! ```toml
//! [stack]
//! hang_timeout_ms = 3000        # no heartbeat for this long: the process is hung, restart it
//! shutdown_grace_ms = 3000      # SIGTERM, then SIGKILL after this long
//!
//! [[process]]
//! name = "camera"               # unique; also the iceoryx2 node name
//! command = "camera"            # a `harvest` subcommand, or instead:
//! # executable = "/path/to/program"  # any other program (test fixtures, vendor tools)
//! args = ["--rate-hz", "30"]     # `${launch_dir}` expands to the launch file's directory
//! restart = "on-failure"        # never | on-failure | always
//! max_restarts = 5              # within restart_window_s, else the process failed for good
//! restart_window_s = 60
//! backoff_initial_ms = 200      # doubles per consecutive restart up to backoff_max_ms
//! backoff_max_ms = 5000
//! critical = true               # failing for good stops the stack (default: see below)
//!
//! [process.scheduling]          # optional; see crate::scheduling
//! realtime_priority = 80        # SCHED_FIFO level 1-99
//! cpus = [1]                    # CPU affinity: CPUs of this machine
//! nice = -5                     # -20..19: normal scheduling (without, or refused, real-time)
//! lock_memory = true            # mlockall before the loop's first tick
//! ```
//!
//! **Criticality.** A critical process that fails for good (its restarts used up) stops the
//! whole stack; a non-critical one is reported (its status line says FAILED, the supervisor
//! publishes its state on `system/health` for the console, the summary names it) and the stack
//! goes on. Without the key, every process is critical except those that only watch or keep a
//! record of the robot ([`NON_CRITICAL_COMMANDS`]: the console, the Foxglove bridge, the
//! recorder): none of them commands anything, and a viewer or a full disk must never be able to
//! end a harvest. The safety monitor is critical: without it no rule is judged.

use crate::scheduling::{self, MAX_REALTIME_PRIORITY, NICE_RANGE, Scheduling};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The launch file used when none is given: the whole stack against simulated hardware.
pub const DEFAULT_LAUNCH: &str = include_str!("../launch/default.toml");
/// What `${launch_dir}` in a process's `args` expands to: the directory of the launch file, so a
/// launch file names the files next to it (calibrations, settings) wherever `harvest up` runs.
/// For the embedded launch files it is their source directory in this repository.
pub const LAUNCH_DIR_VARIABLE: &str = "${launch_dir}";

/// The directory the embedded launch files come from.
pub const EMBEDDED_LAUNCH_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/launch");

/// Name shown for the embedded default launch file in errors.
pub const DEFAULT_LAUNCH_NAME: &str = "<embedded launch/default.toml>";

/// `harvest` subcommands a launch file may start.
pub const KNOWN_COMMANDS: &[&str] = &[
    "sim",
    "camera",
    "perception",
    "arm",
    "vacuum",
    "laser",
    "lidar",
    "recorder",
    "monitor",
    // The operator's mode machine and the viewers (console, Foxglove bridge).
    "executive",
    "console",
    "foxglove",
    // The link to the operator's station (Zenoh).
    "remote",
];

/// `harvest` subcommands that are not critical unless the launch file says `critical = true`
/// (module docs): they only watch the robot or keep its record.
pub const NON_CRITICAL_COMMANDS: &[&str] = &["console", "foxglove", "recorder", "remote"];

/// Whether a process is critical when its launch entry has no `critical` key: every `harvest`
/// subcommand but [`NON_CRITICAL_COMMANDS`], and every other program (`executable = ...`,
/// whose role the supervisor cannot know: stopping is the safe side).
pub fn critical_by_default(command: Option<&str>) -> bool {
    command.is_none_or(|command| !NON_CRITICAL_COMMANDS.contains(&command))
}

/// When a process that exited is started again.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RestartPolicy {
    Never,
    OnFailure,
    Always,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLaunch {
    #[serde(default)]
    stack: StackSettings,
    #[serde(default, rename = "process")]
    processes: Vec<toml::Spanned<RawProcess>>,
}

/// Stack-wide settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StackSettings {
    pub hang_timeout_ms: u64,
    pub shutdown_grace_ms: u64,
    /// A process is not judged hung before this long after its start.
    pub startup_grace_ms: u64,
}

impl Default for StackSettings {
    fn default() -> Self {
        Self {
            hang_timeout_ms: 3000,
            shutdown_grace_ms: 3000,
            startup_grace_ms: 5000,
        }
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProcess {
    name: toml::Spanned<String>,
    #[serde(default)]
    command: Option<toml::Spanned<String>>,
    #[serde(default)]
    executable: Option<PathBuf>,
    #[serde(default)]
    args: Vec<String>,
    #[serde(default = "default_restart")]
    restart: RestartPolicy,
    #[serde(default = "default_max_restarts")]
    max_restarts: u32,
    #[serde(default = "default_restart_window_s")]
    restart_window_s: u64,
    #[serde(default = "default_backoff_initial_ms")]
    backoff_initial_ms: u64,
    #[serde(default = "default_backoff_max_ms")]
    backoff_max_ms: u64,
    #[serde(default)]
    critical: Option<bool>,
    #[serde(default)]
    scheduling: Option<RawScheduling>,
}

/// `[process.scheduling]` as written (integers kept wide so out-of-range values are reported
/// with their line, not as a type error).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScheduling {
    #[serde(default)]
    realtime_priority: Option<toml::Spanned<i64>>,
    #[serde(default)]
    cpus: Option<toml::Spanned<Vec<toml::Spanned<i64>>>>,
    #[serde(default)]
    nice: Option<toml::Spanned<i64>>,
    #[serde(default)]
    lock_memory: bool,
}

fn default_restart() -> RestartPolicy {
    RestartPolicy::OnFailure
}
fn default_max_restarts() -> u32 {
    5
}
fn default_restart_window_s() -> u64 {
    60
}
fn default_backoff_initial_ms() -> u64 {
    200
}
fn default_backoff_max_ms() -> u64 {
    5000
}

/// One process of the launch file, validated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProcessSpec {
    pub name: String,
    /// The `harvest` subcommand, or the executable's path when [`Self::executable`] is set
    /// (for display).
    pub command: String,
    /// A program started instead of a `harvest` subcommand (`executable = ...`).
    pub executable: Option<PathBuf>,
    pub args: Vec<String>,
    pub restart: RestartPolicy,
    pub max_restarts: u32,
    pub restart_window: Duration,
    pub backoff_initial: Duration,
    pub backoff_max: Duration,
    /// Real-time priority, CPU affinity, nice level, memory lock (`[process.scheduling]`).
    pub scheduling: Scheduling,
    /// Failing for good stops the stack (`critical`; default [`critical_by_default`]).
    pub critical: bool,
}

/// A validated launch file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Launch {
    /// Where it came from (a path, or [`DEFAULT_LAUNCH_NAME`]).
    pub source: String,
    pub text: String,
    pub stack: StackSettings,
    pub processes: Vec<ProcessSpec>,
}

/// A launch file that cannot be used. Every variant names the file and the line.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    #[error("cannot read launch file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Syntax errors, unknown keys, bad values (toml reports line, column and key).
    #[error("launch file {file}: {message}")]
    Parse { file: String, message: String },
    #[error(
        "launch file {file}, line {line}: process {name:?}: unknown command {command:?} (known: {known})"
    )]
    UnknownCommand {
        file: String,
        line: usize,
        name: String,
        command: String,
        known: String,
    },
    #[error(
        "launch file {file}, line {line}: duplicate process name {name:?} (first at line {first_line})"
    )]
    DuplicateName {
        file: String,
        line: usize,
        first_line: usize,
        name: String,
    },
    #[error(
        "launch file {file}, line {line}: process name {name:?} must be 1-30 characters of [a-z0-9_-]"
    )]
    BadName {
        file: String,
        line: usize,
        name: String,
    },
    #[error("launch file {file}, line {line}: process {name:?}: {message}")]
    BadValue {
        file: String,
        line: usize,
        name: String,
        message: String,
    },
    /// A `[process.scheduling]` value out of range or not possible on this machine.
    #[error(
        "launch file {file}, line {line}: process {name:?}: `scheduling.{key}` = {value}: {expected}"
    )]
    BadScheduling {
        file: String,
        line: usize,
        name: String,
        key: &'static str,
        value: String,
        expected: String,
    },
    #[error("launch file {file}: no [[process]] entries")]
    Empty { file: String },
}

impl Launch {
    /// Reads and validates a launch file.
    pub fn from_path(path: &Path) -> Result<Self, LaunchError> {
        let text = std::fs::read_to_string(path).map_err(|source| LaunchError::Read {
            path: path.to_owned(),
            source,
        })?;
        let dir = match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent.to_owned(),
            _ => PathBuf::from("."),
        };
        let dir = std::fs::canonicalize(&dir).unwrap_or(dir);
        Self::parse_in(&text, &path.display().to_string(), &dir)
    }

    /// The embedded default launch file.
    pub fn default_stack() -> Result<Self, LaunchError> {
        Self::parse_in(
            DEFAULT_LAUNCH,
            DEFAULT_LAUNCH_NAME,
            Path::new(EMBEDDED_LAUNCH_DIR),
        )
    }

    /// Parses and validates an embedded launch file (`${launch_dir}` is
    /// [`EMBEDDED_LAUNCH_DIR`]); `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Self, LaunchError> {
        Self::parse_in(text, file, Path::new(EMBEDDED_LAUNCH_DIR))
    }

    /// Parses and validates launch-file text whose `${launch_dir}` is `launch_dir`; `file` names
    /// it in errors.
    pub fn parse_in(text: &str, file: &str, launch_dir: &Path) -> Result<Self, LaunchError> {
        let launch_dir_text = launch_dir.display().to_string();
        let raw: RawLaunch = toml::from_str(text).map_err(|error| LaunchError::Parse {
            file: file.to_owned(),
            message: error.to_string(),
        })?;
        let line_of = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
        let mut processes: Vec<ProcessSpec> = Vec::new();
        let mut first_lines: Vec<usize> = Vec::new();
        for spanned in raw.processes {
            let process = spanned.into_inner();
            let name_line = line_of(process.name.span().start);
            let name = process.name.into_inner();
            let valid_name = !name.is_empty()
                && name.len() <= 30
                && name.bytes().all(|b| {
                    b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-'
                });
            if !valid_name {
                return Err(LaunchError::BadName {
                    file: file.to_owned(),
                    line: name_line,
                    name,
                });
            }
            if let Some(index) = processes.iter().position(|p| p.name == name) {
                return Err(LaunchError::DuplicateName {
                    file: file.to_owned(),
                    line: name_line,
                    first_line: first_lines[index],
                    name,
                });
            }
            let critical = process.critical.unwrap_or_else(|| {
                critical_by_default(process.command.as_ref().map(|c| c.get_ref().as_str()))
            });
            let command = match (process.command, &process.executable) {
                (Some(command), None) => {
                    let command_line = line_of(command.span().start);
                    let command = command.into_inner();
                    if !KNOWN_COMMANDS.contains(&command.as_str()) {
                        return Err(LaunchError::UnknownCommand {
                            file: file.to_owned(),
                            line: command_line,
                            name,
                            command,
                            known: KNOWN_COMMANDS.join(", "),
                        });
                    }
                    command
                }
                (None, Some(executable)) => executable.display().to_string(),
                (command, _) => {
                    return Err(LaunchError::BadValue {
                        file: file.to_owned(),
                        line: name_line,
                        name,
                        message: if command.is_some() {
                            "give either `command` or `executable`, not both".to_owned()
                        } else {
                            "missing `command` (a harvest subcommand) or `executable`".to_owned()
                        },
                    });
                }
            };
            if process.backoff_initial_ms > process.backoff_max_ms || process.restart_window_s == 0
            {
                return Err(LaunchError::BadValue {
                    file: file.to_owned(),
                    line: name_line,
                    name,
                    message: "need backoff_initial_ms <= backoff_max_ms and restart_window_s > 0"
                        .to_owned(),
                });
            }
            let scheduling = match process.scheduling {
                Some(raw) => validate_scheduling(raw, &line_of).map_err(|bad| {
                    LaunchError::BadScheduling {
                        file: file.to_owned(),
                        line: bad.line,
                        name: name.clone(),
                        key: bad.key,
                        value: bad.value,
                        expected: bad.expected,
                    }
                })?,
                None => Scheduling::default(),
            };
            first_lines.push(name_line);
            processes.push(ProcessSpec {
                name,
                command,
                executable: process.executable,
                args: process
                    .args
                    .iter()
                    .map(|arg| arg.replace(LAUNCH_DIR_VARIABLE, &launch_dir_text))
                    .collect(),
                restart: process.restart,
                max_restarts: process.max_restarts,
                restart_window: Duration::from_secs(process.restart_window_s),
                backoff_initial: Duration::from_millis(process.backoff_initial_ms),
                backoff_max: Duration::from_millis(process.backoff_max_ms),
                scheduling,
                critical,
            });
        }
        if processes.is_empty() {
            return Err(LaunchError::Empty {
                file: file.to_owned(),
            });
        }
        Ok(Self {
            source: file.to_owned(),
            text: text.to_owned(),
            stack: raw.stack,
            processes,
        })
    }
}

impl Launch {
    /// The same launch file with every process's scheduling settings dropped (`harvest up
    /// --no-scheduling`, and the bench's comparison run).
    pub fn without_scheduling(mut self) -> Self {
        for process in &mut self.processes {
            process.scheduling = Scheduling::default();
        }
        self
    }
}

/// A scheduling value that cannot be used, with its line.
struct BadSchedulingValue {
    line: usize,
    key: &'static str,
    value: String,
    expected: String,
}

fn validate_scheduling(
    raw: RawScheduling,
    line_of: &dyn Fn(usize) -> usize,
) -> Result<Scheduling, BadSchedulingValue> {
    let realtime_priority = match raw.realtime_priority {
        Some(priority) => {
            let line = line_of(priority.span().start);
            let value = priority.into_inner();
            match u8::try_from(value) {
                Ok(level) if (1..=MAX_REALTIME_PRIORITY).contains(&level) => Some(level),
                _ => {
                    return Err(BadSchedulingValue {
                        line,
                        key: "realtime_priority",
                        value: value.to_string(),
                        expected: format!("expected a SCHED_FIFO level 1-{MAX_REALTIME_PRIORITY}"),
                    });
                }
            }
        }
        None => None,
    };
    let nice = match raw.nice {
        Some(nice) => {
            let line = line_of(nice.span().start);
            let value = nice.into_inner();
            match i8::try_from(value) {
                Ok(level) if NICE_RANGE.contains(&level) => Some(level),
                _ => {
                    return Err(BadSchedulingValue {
                        line,
                        key: "nice",
                        value: value.to_string(),
                        expected: format!(
                            "expected a nice level {}..{}",
                            NICE_RANGE.start(),
                            NICE_RANGE.end()
                        ),
                    });
                }
            }
        }
        None => None,
    };
    let mut cpus = Vec::new();
    if let Some(list) = raw.cpus {
        let list_line = line_of(list.span().start);
        let entries = list.into_inner();
        if entries.is_empty() {
            return Err(BadSchedulingValue {
                line: list_line,
                key: "cpus",
                value: "[]".to_owned(),
                expected: "expected at least one CPU (leave the key out to allow any)".to_owned(),
            });
        }
        let online = scheduling::online_cpus();
        for entry in entries {
            let line = line_of(entry.span().start);
            let value = entry.into_inner();
            match usize::try_from(value) {
                Ok(cpu) if online.contains(&cpu) => {
                    if !cpus.contains(&cpu) {
                        cpus.push(cpu);
                    }
                }
                _ => {
                    return Err(BadSchedulingValue {
                        line,
                        key: "cpus",
                        value: value.to_string(),
                        expected: format!(
                            "CPU {value} is not on this machine (online CPUs: {})",
                            scheduling::cpu_list(&online)
                        ),
                    });
                }
            }
        }
    }
    Ok(Scheduling {
        realtime_priority,
        cpus,
        nice,
        lock_memory: raw.lock_memory,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "[stack]\nhang_timeout_ms = 2000\n\n[[process]]\nname = \"cam\"\ncommand = \"camera\"\n\n[[process]]\nname = \"perc\"\ncommand = \"perception\"\nrestart = \"always\"\n";

    #[test]
    fn default_launch_is_valid() {
        let launch = Launch::default_stack().expect("default launch parses");
        assert!(launch.processes.iter().any(|p| p.command == "camera"));
    }

    #[test]
    fn every_shipped_launch_file_is_valid() {
        let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("launch");
        let mut checked = 0;
        for entry in std::fs::read_dir(&folder).expect("launch folder") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|ext| ext == "toml") {
                let launch = Launch::from_path(&path)
                    .unwrap_or_else(|error| panic!("{}: {error}", path.display()));
                assert!(!launch.processes.is_empty(), "{}", path.display());
                checked += 1;
            }
        }
        assert!(checked >= 2, "default and lidar profiles at least");
    }

    #[test]
    fn parses_good_file() {
        let launch = Launch::parse(GOOD, "good.toml").expect("parses");
        assert_eq!(launch.stack.hang_timeout_ms, 2000);
        assert_eq!(launch.processes[1].restart, RestartPolicy::Always);
        assert_eq!(launch.processes[0].restart, RestartPolicy::OnFailure);
    }

    #[test]
    fn criticality_defaults_by_role_and_the_key_overrides_it() {
        let text = "[[process]]\nname = \"monitor\"\ncommand = \"monitor\"\n\n\
[[process]]\nname = \"console\"\ncommand = \"console\"\n\n\
[[process]]\nname = \"foxglove\"\ncommand = \"foxglove\"\n\n\
[[process]]\nname = \"recorder\"\ncommand = \"recorder\"\ncritical = true\n\n\
[[process]]\nname = \"tool\"\nexecutable = \"/bin/true\"\n\n\
[[process]]\nname = \"arm1\"\ncommand = \"arm\"\ncritical = false\n";
        let launch = Launch::parse(text, "critical.toml").expect("parses");
        let critical: Vec<(&str, bool)> = launch
            .processes
            .iter()
            .map(|p| (p.name.as_str(), p.critical))
            .collect();
        assert_eq!(
            critical,
            [
                ("monitor", true),
                ("console", false),
                ("foxglove", false),
                ("recorder", true),
                ("tool", true),
                ("arm1", false),
            ]
        );
        let message = Launch::parse(
            &text.replace("critical = true", "critical = \"yes\""),
            "critical.toml",
        )
        .expect_err("not a boolean")
        .to_string();
        assert!(
            message.contains("critical.toml") && message.contains("line 16"),
            "{message}"
        );
    }

    #[test]
    fn shipped_launch_files_say_what_is_critical() {
        for (text, name) in [
            (DEFAULT_LAUNCH, "default.toml"),
            (include_str!("../launch/lidar.toml"), "lidar.toml"),
            (include_str!("../launch/row.toml"), "row.toml"),
        ] {
            let launch = Launch::parse(text, name).expect("parses");
            for process in &launch.processes {
                let expected = !NON_CRITICAL_COMMANDS.contains(&process.command.as_str());
                assert_eq!(process.critical, expected, "{name}: {}", process.name);
            }
        }
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let text = GOOD.replace("restart = \"always\"", "restrat = \"always\"");
        let message = Launch::parse(&text, "bad.toml")
            .expect_err("unknown key")
            .to_string();
        assert!(message.contains("bad.toml"), "{message}");
        assert!(message.contains("restrat"), "{message}");
        assert!(message.contains("line 11"), "{message}");
    }

    #[test]
    fn bad_restart_policy_is_named() {
        let text = GOOD.replace("restart = \"always\"", "restart = \"sometimes\"");
        let message = Launch::parse(&text, "bad.toml")
            .expect_err("bad policy")
            .to_string();
        assert!(
            message.contains("sometimes") && message.contains("line 11"),
            "{message}"
        );
    }

    #[test]
    fn unknown_command_names_line() {
        let text = GOOD.replace("command = \"perception\"", "command = \"percepshun\"");
        let error = Launch::parse(&text, "bad.toml").expect_err("unknown command");
        assert!(
            matches!(error, LaunchError::UnknownCommand { line: 10, .. }),
            "{error}"
        );
    }

    const SCHEDULED: &str = "[[process]]\nname = \"arm1\"\ncommand = \"arm\"\n\n[process.scheduling]\nrealtime_priority = 80\ncpus = [0]\nnice = -5\nlock_memory = true\n";

    #[test]
    fn scheduling_parses_and_can_be_dropped() {
        let launch = Launch::parse(SCHEDULED, "rt.toml").expect("parses");
        let scheduling = &launch.processes[0].scheduling;
        assert_eq!(scheduling.realtime_priority, Some(80));
        assert_eq!(scheduling.cpus, vec![0]);
        assert_eq!(scheduling.nice, Some(-5));
        assert!(scheduling.lock_memory);
        let plain = launch.without_scheduling();
        assert!(plain.processes[0].scheduling.is_default());
        // Inline table form, and no table at all.
        let inline = "[[process]]\nname = \"v\"\ncommand = \"vacuum\"\nscheduling = { realtime_priority = 1 }\n";
        let launch = Launch::parse(inline, "rt.toml").expect("parses");
        assert_eq!(launch.processes[0].scheduling.realtime_priority, Some(1));
        let launch = Launch::parse(GOOD, "good.toml").expect("parses");
        assert!(launch.processes[0].scheduling.is_default());
    }

    fn scheduling_error(from: &str, to: &str) -> String {
        let text = SCHEDULED.replace(from, to);
        Launch::parse(&text, "rt.toml")
            .expect_err("bad scheduling")
            .to_string()
    }

    #[test]
    fn bad_scheduling_values_name_file_line_and_key() {
        for (from, to, key, line) in [
            (
                "realtime_priority = 80",
                "realtime_priority = 0",
                "scheduling.realtime_priority` = 0",
                6,
            ),
            (
                "realtime_priority = 80",
                "realtime_priority = 100",
                "scheduling.realtime_priority` = 100",
                6,
            ),
            ("nice = -5", "nice = -21", "scheduling.nice` = -21", 8),
            ("nice = -5", "nice = 20", "scheduling.nice` = 20", 8),
            (
                "cpus = [0]",
                "cpus = [0, 4096]",
                "scheduling.cpus` = 4096",
                7,
            ),
            ("cpus = [0]", "cpus = [-1]", "scheduling.cpus` = -1", 7),
            ("cpus = [0]", "cpus = []", "scheduling.cpus` = []", 7),
        ] {
            let message = scheduling_error(from, to);
            assert!(message.starts_with("launch file rt.toml"), "{message}");
            assert!(message.contains(key), "{message}");
            assert!(message.contains(&format!("line {line}:")), "{message}");
            assert!(message.contains("\"arm1\""), "{message}");
        }
        assert!(scheduling_error("cpus = [0]", "cpus = [4096]").contains("not on this machine"));
        // Unknown keys and wrong types: toml names the key and the line.
        let message = scheduling_error("nice = -5", "niceness = -5");
        assert!(
            message.contains("niceness") && message.contains("line 8"),
            "{message}"
        );
        let message = scheduling_error("lock_memory = true", "lock_memory = \"yes\"");
        assert!(message.contains("line 9"), "{message}");
    }

    #[test]
    fn duplicate_name_names_both_lines() {
        let text = GOOD.replace("name = \"perc\"", "name = \"cam\"");
        let error = Launch::parse(&text, "bad.toml").expect_err("duplicate");
        assert!(
            matches!(
                error,
                LaunchError::DuplicateName {
                    line: 9,
                    first_line: 5,
                    ..
                }
            ),
            "{error}"
        );
    }
}
