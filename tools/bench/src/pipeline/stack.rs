//! The stack under test: `harvest up --launch <file>` as a child process in the run's domain,
//! stopped cleanly (SIGTERM to the supervisor, which stops its processes in reverse order) at
//! the end.

use crate::child_stop::up_command;
use crate::error::BenchError;
use harvest_ipc::Domain;
use std::path::{Path, PathBuf};
use std::process::{Child, ExitStatus, Stdio};
use std::time::Duration;

/// The bench's own launch file (sim, camera, perception, vacuum, both arms; no recorder).
pub const PIPELINE_LAUNCH: &str = include_str!("../../launch/pipeline.toml");
/// How long the supervisor gets to stop the stack after SIGTERM before it is killed.
pub const STOP_GRACE: Duration = Duration::from_secs(30);
/// Added to the run's length for `harvest up --duration`, so the stack stops by itself even if
/// the bench is killed before it can stop it.
const SAFETY_MARGIN: Duration = Duration::from_secs(60);

/// A running `harvest up`.
pub struct Stack {
    child: Child,
    reaped: Option<ExitStatus>,
    /// The supervisor's stderr (status lines, process logs).
    pub log_path: PathBuf,
    /// The launch file written for the embedded default, removed at the end.
    written_launch: Option<PathBuf>,
}

impl Stack {
    /// Starts `executable up --launch <launch>` in `domain`. `launch` None: the embedded
    /// [`PIPELINE_LAUNCH`], written to a temporary file. `run_for` is how long the bench means
    /// to run (the stack's own `--duration` is that plus a margin). `no_scheduling`: `harvest up
    /// --no-scheduling` (the launch file's `[process.scheduling]` settings dropped).
    pub fn start(
        executable: &Path,
        domain: &Domain,
        launch: Option<&Path>,
        run_for: Duration,
        no_scheduling: bool,
    ) -> Result<Self, BenchError> {
        let scratch = std::env::temp_dir();
        let stem = format!("harvest-bench-pipeline-{}", domain.name());
        let (launch_path, written_launch) = match launch {
            Some(path) => (path.to_owned(), None),
            None => {
                let path = scratch.join(format!("{stem}.toml"));
                // The copy in the scratch directory names the files beside the original.
                let text = PIPELINE_LAUNCH.replace(
                    harvest_supervisor::launch::LAUNCH_DIR_VARIABLE,
                    concat!(env!("CARGO_MANIFEST_DIR"), "/launch"),
                );
                std::fs::write(&path, text).map_err(|source| BenchError::WriteOutput {
                    path: path.clone(),
                    source,
                })?;
                (path.clone(), Some(path))
            }
        };
        let log_path = scratch.join(format!("{stem}.log"));
        let log = std::fs::File::create(&log_path).map_err(|source| BenchError::WriteOutput {
            path: log_path.clone(),
            source,
        })?;
        let child = up_command(executable, domain, &launch_path, run_for + SAFETY_MARGIN)
            .args(no_scheduling.then_some("--no-scheduling"))
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .map_err(|source| BenchError::Spawn {
                exe: executable.to_owned(),
                source,
            })?;
        tracing::info!(
            pid = child.id(),
            domain = domain.name(),
            launch = %launch_path.display(),
            log = %log_path.display(),
            "stack started"
        );
        Ok(Self {
            child,
            reaped: None,
            log_path,
            written_launch,
        })
    }

    /// Fails if the stack already ended (a process failed for good, a bad launch file).
    pub fn check_running(&mut self) -> Result<(), BenchError> {
        if self.reaped.is_none()
            && let Ok(Some(status)) = self.child.try_wait()
        {
            self.reaped = Some(status);
        }
        match self.reaped {
            Some(status) => Err(BenchError::StackEnded {
                status,
                log: self.log_path.clone(),
                tail: log_tail(&self.log_path),
            }),
            None => Ok(()),
        }
    }

    /// SIGTERM to the supervisor and waits for it (SIGKILL after [`STOP_GRACE`]). Returns its
    /// exit status.
    pub fn stop(mut self) -> Result<ExitStatus, BenchError> {
        let status = self.terminate();
        status.ok_or_else(|| BenchError::StackStop {
            log: self.log_path.clone(),
        })
    }

    fn terminate(&mut self) -> Option<ExitStatus> {
        if let Some(status) = self.reaped {
            return Some(status);
        }
        self.reaped = crate::child_stop::terminate(&mut self.child, STOP_GRACE);
        self.reaped
    }
}

impl Drop for Stack {
    fn drop(&mut self) {
        self.terminate();
        if let Some(path) = &self.written_launch
            && let Err(error) = std::fs::remove_file(path)
        {
            tracing::debug!(path = %path.display(), %error, "launch file already removed");
        }
    }
}

/// The last lines of the stack's log, for error messages.
fn log_tail(path: &Path) -> String {
    const LINES: usize = 15;
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(LINES)..].join("\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_supervisor::Launch;

    #[test]
    fn embedded_launch_file_is_valid_and_runs_the_control_path() {
        let launch = Launch::parse(PIPELINE_LAUNCH, "pipeline.toml").expect("valid launch file");
        let commands: Vec<&str> = launch
            .processes
            .iter()
            .map(|p| p.command.as_str())
            .collect();
        for needed in ["sim", "camera", "perception", "vacuum", "arm"] {
            assert!(commands.contains(&needed), "{needed} missing: {commands:?}");
        }
        let arms: Vec<&[String]> = launch
            .processes
            .iter()
            .filter(|p| p.command == "arm")
            .map(|p| p.args.as_slice())
            .collect();
        assert_eq!(arms.len(), 2);
        assert!(!commands.contains(&"recorder"));
        // No executive: the nodes that obey the operator are told so, else they hold.
        assert!(!commands.contains(&"executive"));
        for process in launch
            .processes
            .iter()
            .filter(|p| p.command == "arm" || p.command == "vacuum")
        {
            assert!(
                process.args.iter().any(|a| a == "--without-operator"),
                "{}: {:?}",
                process.name,
                process.args
            );
        }
    }

    #[test]
    fn log_tail_keeps_the_last_lines() {
        let path = std::env::temp_dir().join(format!("bench-tail-{}.log", std::process::id()));
        let text: String = (1..=40).map(|i| format!("line {i}\n")).collect();
        std::fs::write(&path, text).expect("write");
        let tail = log_tail(&path);
        assert!(
            tail.starts_with("line 26") && tail.ends_with("line 40"),
            "{tail}"
        );
        std::fs::remove_file(&path).expect("remove");
        assert_eq!(log_tail(&path), "");
    }
}
