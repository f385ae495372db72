//! Stopping a `harvest up` child the way its supervisor wants to be stopped: SIGTERM (it stops
//! its processes in reverse start order), then SIGKILL if it has not exited after a grace.

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use std::process::{Child, ExitStatus};
use std::time::{Duration, Instant};

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
