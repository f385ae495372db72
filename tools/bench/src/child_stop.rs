//! A `harvest up` child of a benchmark or soak: started in its own domain so that it cannot
//! outlive its parent, and stopped the way its supervisor wants to be stopped: SIGTERM (it stops
//! its processes in reverse start order), then SIGKILL if it has not exited after a grace.

use harvest_ipc::Domain;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// `executable --domain D up --launch L --duration T` with no stdin, `$HARVEST_DOMAIN` removed
/// and SIGTERM sent to it when its parent dies; the caller adds the output files and options.
pub fn up_command(
    executable: &Path,
    domain: &Domain,
    launch: &Path,
    duration: Duration,
) -> Command {
    let mut command = Command::new(executable);
    command
        .arg("--domain")
        .arg(domain.name())
        .arg("up")
        .arg("--launch")
        .arg(launch)
        .arg("--duration")
        .arg(format!("{}ms", duration.as_millis()))
        .env_remove(harvest_ipc::domain::DOMAIN_ENV)
        .stdin(Stdio::null());
    // SAFETY: the closure runs in the forked child before exec and only calls prctl, which is
    // async-signal-safe. The stack must not outlive its parent.
    unsafe {
        command.pre_exec(|| {
            nix::sys::prctl::set_pdeathsig(Some(Signal::SIGTERM)).map_err(std::io::Error::from)
        });
    }
    command
}

/// SIGTERM to `child`, waits up to `grace` for it, then SIGKILLs it; returns its exit status
/// (None if it could not be waited for).
pub fn terminate(child: &mut Child, grace: Duration) -> Option<ExitStatus> {
    if let Err(error) = kill(Pid::from_raw(child.id() as i32), Signal::SIGTERM) {
        tracing::debug!(%error, "stack already gone");
    }
    let start = Instant::now();
    while start.elapsed() < grace {
        match child.try_wait() {
            Ok(Some(status)) => return Some(status),
            Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            Err(error) => {
                tracing::warn!(%error, "cannot wait for the stack");
                break;
            }
        }
    }
    tracing::warn!("stack did not stop in time: killing the supervisor");
    let _ = child.kill();
    child.wait().ok()
}
