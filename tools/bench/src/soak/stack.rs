//! The stack under soak: the embedded default launch file (`harvest up` without `--launch`),
//! copied to the run's scratch directory with two changes so that a soak can run beside another
//! stack on the same machine: the console and the Foxglove bridge listen on free ports instead of
//! 8080 and 8765. `harvest up` runs as a child process in the soak's own domain, with the scratch
//! directory as its working directory (the recorder's `recordings/` lands there), and is stopped
//! with SIGTERM at the end; its final summaries (stdout, stderr) are parsed.

use super::error::SoakError;
use crate::child_stop::up_command;
use harvest_ipc::Domain;
use harvest_supervisor::Launch;
use harvest_supervisor::launch::{DEFAULT_LAUNCH, EMBEDDED_LAUNCH_DIR, LAUNCH_DIR_VARIABLE};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

/// How long `harvest up` gets to come up (its control token file written).
const START_TIMEOUT: Duration = Duration::from_secs(60);
/// How long the supervisor gets to stop the stack after SIGTERM before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(90);
/// Added to the soak's length for `harvest up --duration`: the stack stops by itself even if the
/// soak is killed before it can stop it.
const SAFETY_MARGIN: Duration = Duration::from_secs(120);

/// The default launch file as the soak runs it.
#[derive(Debug, Clone)]
pub struct SoakLaunch {
    pub text: String,
    pub launch: Launch,
    pub console_port: u16,
    pub foxglove_port: u16,
}

impl SoakLaunch {
    /// The embedded default launch file with `${launch_dir}` resolved and the console and the
    /// Foxglove bridge on the given ports.
    pub fn default_stack(console_port: u16, foxglove_port: u16) -> Result<Self, SoakError> {
        let text = DEFAULT_LAUNCH.replace(LAUNCH_DIR_VARIABLE, EMBEDDED_LAUNCH_DIR);
        let text = add_args(
            &text,
            "console",
            &["--listen", &format!("127.0.0.1:{console_port}")],
        )?;
        let text = add_args(
            &text,
            "foxglove",
            &["--listen", &format!("127.0.0.1:{foxglove_port}")],
        )?;
        let launch = Launch::parse(&text, "<soak copy of launch/default.toml>")?;
        Ok(Self {
            text,
            launch,
            console_port,
            foxglove_port,
        })
    }

    /// The launch names of the processes, in start order.
    pub fn process_names(&self) -> Vec<String> {
        self.launch
            .processes
            .iter()
            .map(|p| p.name.clone())
            .collect()
    }
}

/// Puts `args` first in the `args` of process `name` (adding the key after its `command` line
/// when it has none).
fn add_args(text: &str, name: &str, args: &[&str]) -> Result<String, SoakError> {
    const BLOCK: &str = "[[process]]";
    let name_line = format!("name = \"{name}\"");
    let quoted: Vec<String> = args.iter().map(|a| format!("{a:?}")).collect();
    let mut out = String::with_capacity(text.len() + 64);
    let mut found = false;
    for (index, block) in text.split(BLOCK).enumerate() {
        if index > 0 {
            out.push_str(BLOCK);
        }
        if !block.lines().any(|line| line.trim() == name_line) {
            out.push_str(block);
            continue;
        }
        found = true;
        if let Some(at) = block.find("\nargs = [") {
            let insert_at = at + "\nargs = [".len();
            out.push_str(&block[..insert_at]);
            out.push_str(&quoted.join(", "));
            out.push_str(", ");
            out.push_str(&block[insert_at..]);
        } else {
            let Some(command_at) = block.find("\ncommand = ") else {
                return Err(SoakError::LaunchChanged {
                    what: format!("process {name:?} has no `command` line"),
                });
            };
            let line_end = block[command_at + 1..]
                .find('\n')
                .map_or(block.len(), |end| command_at + 1 + end);
            out.push_str(&block[..line_end]);
            out.push_str(&format!("\nargs = [{}]", quoted.join(", ")));
            out.push_str(&block[line_end..]);
        }
    }
    if found {
        Ok(out)
    } else {
        Err(SoakError::LaunchChanged {
            what: format!("no process {name:?}"),
        })
    }
}

/// A free TCP port on the loopback interface (bound, then released for the stack).
pub fn free_port() -> Result<u16, SoakError> {
    let listener =
        std::net::TcpListener::bind("127.0.0.1:0").map_err(|source| SoakError::File {
            path: PathBuf::from("127.0.0.1:0"),
            source,
        })?;
    let port = listener
        .local_addr()
        .map_err(|source| SoakError::File {
            path: PathBuf::from("127.0.0.1:0"),
            source,
        })?
        .port();
    Ok(port)
}

/// A running `harvest up`.
pub struct SoakStack {
    child: Child,
    reaped: Option<ExitStatus>,
    started: Instant,
    /// The supervisor's stderr (status lines, process logs, the process summary).
    pub log_path: PathBuf,
    /// The supervisor's stdout (harvest events, the harvest summary, safety violations).
    pub stdout_path: PathBuf,
}

impl SoakStack {
    /// Starts `executable --domain D up --launch <scratch>/launch.toml --duration ...` in
    /// `scratch` and waits for its control token file.
    pub fn start(
        executable: &Path,
        domain: &Domain,
        launch: &SoakLaunch,
        scratch: &Path,
        run_for: Duration,
    ) -> Result<Self, SoakError> {
        let launch_path = scratch.join("launch.toml");
        write(&launch_path, &launch.text)?;
        let log_path = scratch.join("stack.log");
        let stdout_path = scratch.join("stack.stdout");
        let log = create(&log_path)?;
        let stdout = create(&stdout_path)?;
        let child = up_command(executable, domain, &launch_path, run_for + SAFETY_MARGIN)
            .current_dir(scratch)
            .stdout(stdout)
            .stderr(log)
            .spawn()
            .map_err(|source| SoakError::Spawn {
                exe: executable.to_owned(),
                source,
            })?;
        let mut stack = Self {
            child,
            reaped: None,
            started: Instant::now(),
            log_path,
            stdout_path,
        };
        tracing::info!(pid = stack.pid(), domain = domain.name(), log = %stack.log_path.display(), "stack started");
        let token_file = harvest_operator::token::token_path(domain.name());
        while !token_file.exists() {
            stack.check_running()?;
            if stack.started.elapsed() > START_TIMEOUT {
                return Err(SoakError::StackNotStarted {
                    waited_s: START_TIMEOUT.as_secs(),
                    log: stack.log_path.clone(),
                    tail: log_tail(&stack.log_path),
                });
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        Ok(stack)
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Fails if `harvest up` already ended (a process failed for good, a bad launch file).
    pub fn check_running(&mut self) -> Result<(), SoakError> {
        if self.reaped.is_none()
            && let Ok(Some(status)) = self.child.try_wait()
        {
            self.reaped = Some(status);
        }
        match self.reaped {
            Some(status) => Err(SoakError::StackEnded {
                status,
                after_s: self.started.elapsed().as_secs_f64(),
                log: self.log_path.clone(),
                tail: log_tail(&self.log_path),
            }),
            None => Ok(()),
        }
    }

    /// SIGTERM to the supervisor, waits for it (SIGKILL after `STOP_GRACE`); returns its exit
    /// status (None if it could not be waited for).
    pub fn stop(&mut self) -> Option<ExitStatus> {
        if let Some(status) = self.reaped {
            return Some(status);
        }
        self.reaped = crate::child_stop::terminate(&mut self.child, STOP_GRACE);
        self.reaped
    }
}

impl Drop for SoakStack {
    fn drop(&mut self) {
        self.stop();
    }
}

fn create(path: &Path) -> Result<std::fs::File, SoakError> {
    std::fs::File::create(path).map_err(|source| SoakError::File {
        path: path.to_owned(),
        source,
    })
}

fn write(path: &Path, text: &str) -> Result<(), SoakError> {
    std::fs::write(path, text).map_err(|source| SoakError::File {
        path: path.to_owned(),
        source,
    })
}

/// The last lines of the stack's log, for error messages.
pub fn log_tail(path: &Path) -> String {
    const LINES: usize = 20;
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(LINES)..].join("\n")
}

/// What `harvest up` printed at its end.
#[derive(Debug, Clone, Default, Serialize)]
pub struct StackSummary {
    /// `harvest up ended: <why>`.
    pub ended_by: Option<String>,
    /// Per process: (name, final state, restarts, last exit).
    pub processes: Vec<ProcessLine>,
    /// `harvest summary: attempted A, harvested H ...` (the whole line).
    pub harvest_line: Option<String>,
    pub attempted: Option<u32>,
    pub harvested: Option<u32>,
    /// `safety violations: N` and the `VIOLATION` lines.
    pub safety_violations: Option<u32>,
    pub violation_lines: Vec<String>,
    /// `warning: N iceoryx2 files of this domain remain`.
    pub leftover_files: Option<u32>,
}

/// One line of the process summary.
#[derive(Debug, Clone, Serialize)]
pub struct ProcessLine {
    pub name: String,
    pub state: String,
    pub restarts: u32,
    pub last_exit: String,
}

impl StackSummary {
    /// Parses the supervisor's stdout and stderr.
    pub fn parse(stdout: &str, stderr: &str) -> Self {
        let mut summary = Self::default();
        for line in stdout.lines() {
            if let Some(rest) = line.strip_prefix("harvest summary: ") {
                summary.harvest_line = Some(line.to_owned());
                summary.attempted = number_after(rest, "attempted ");
                summary.harvested = number_after(rest, "harvested ");
            } else if let Some(rest) = line.strip_prefix("safety violations: ") {
                summary.safety_violations = rest.trim().parse().ok();
            } else if let Some(rest) = line.trim_start().strip_prefix("VIOLATION ") {
                summary.violation_lines.push(rest.to_owned());
            }
        }
        let mut in_summary = false;
        for line in stderr.lines() {
            if let Some(rest) = line.strip_prefix("harvest up ended: ") {
                summary.ended_by = Some(rest.to_owned());
                summary.processes.clear();
                in_summary = true;
                continue;
            }
            if let Some(rest) = line.strip_prefix("warning: ")
                && rest.contains("iceoryx2 files of this domain remain")
            {
                summary.leftover_files = number_after(rest, "");
            }
            if !in_summary {
                continue;
            }
            match parse_process_line(line) {
                Some(process) => summary.processes.push(process),
                None => in_summary = line.starts_with("  "),
            }
        }
        summary
    }

    /// The supervisor's restart count of `name`.
    pub fn restarts_of(&self, name: &str) -> Option<u32> {
        self.processes
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.restarts)
    }
}

/// `  arm1         stopped    restarts 1  messages 1234     last exit: killed by SIGTERM`
fn parse_process_line(line: &str) -> Option<ProcessLine> {
    if !line.starts_with("  ") {
        return None;
    }
    let mut words = line.split_whitespace();
    let name = words.next()?.to_owned();
    let state = words.next()?.to_owned();
    if words.next()? != "restarts" {
        return None;
    }
    let restarts = words.next()?.parse().ok()?;
    let last_exit = line
        .split_once("last exit: ")
        .map(|(_, rest)| rest.trim().to_owned())
        .unwrap_or_default();
    Some(ProcessLine {
        name,
        state,
        restarts,
        last_exit,
    })
}

/// The number right after `key` in `text`.
fn number_after(text: &str, key: &str) -> Option<u32> {
    let rest = &text[text.find(key)? + key.len()..];
    let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
    digits.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_copy_is_the_default_stack_on_other_ports() {
        let launch = SoakLaunch::default_stack(18080, 18765).expect("rewritten default launch");
        let default = Launch::default_stack().expect("default launch");
        assert_eq!(launch.launch.processes.len(), default.processes.len());
        for (copy, original) in launch.launch.processes.iter().zip(&default.processes) {
            assert_eq!(copy.name, original.name);
            match copy.name.as_str() {
                "console" | "foxglove" => {
                    let port = if copy.name == "console" { 18080 } else { 18765 };
                    assert_eq!(
                        copy.args[..2],
                        ["--listen".to_owned(), format!("127.0.0.1:{port}")]
                    );
                    assert_eq!(copy.args[2..], original.args[..]);
                }
                _ => assert_eq!(copy.args, original.args, "{}", copy.name),
            }
        }
        assert!(!launch.text.contains(LAUNCH_DIR_VARIABLE));
    }

    #[test]
    fn a_missing_process_is_named() {
        let error = add_args(
            "[[process]]\nname = \"sim\"\ncommand = \"sim\"\n",
            "console",
            &[],
        )
        .expect_err("no console");
        assert!(error.to_string().contains("\"console\""), "{error}");
    }

    #[test]
    fn summaries_are_parsed() {
        let stdout = "arm1 apple 3 harvested\nharvest summary: attempted 17, harvested 15 (success \
88.2 %), first-attempt successes 14, not complete\n  attempts 19\nsafety violations: 1\n  \
VIOLATION BothValvesOpen: x (protective stop requested)\n";
        let stderr = "harvest up: 5s\n  sim  running pid 4 restarts 0\nharvest up ended: \
SIGINT/SIGTERM\n  sim          stopped    restarts 2  messages 100      last exit: exit code 0\n  \
arm1         stopped    restarts 0  messages 5        last exit: killed by SIGTERM  [fifo81]\n\
warning: 3 iceoryx2 files of this domain remain\n2026 some later log line\n";
        let summary = StackSummary::parse(stdout, stderr);
        assert_eq!(summary.attempted, Some(17));
        assert_eq!(summary.harvested, Some(15));
        assert_eq!(summary.safety_violations, Some(1));
        assert_eq!(summary.violation_lines.len(), 1);
        assert_eq!(summary.ended_by.as_deref(), Some("SIGINT/SIGTERM"));
        assert_eq!(summary.processes.len(), 2);
        assert_eq!(summary.restarts_of("sim"), Some(2));
        assert_eq!(summary.restarts_of("arm1"), Some(0));
        assert_eq!(summary.leftover_files, Some(3));
        assert!(
            summary.processes[1]
                .last_exit
                .starts_with("killed by SIGTERM")
        );
    }
}
