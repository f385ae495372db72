//! Starting and signalling one child process.

use crate::launch::ProcessSpec;
use crate::scheduling::{OutcomePipe, SchedulingOutcome};
use harvest_ipc::Domain;
use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use std::os::fd::RawFd;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command};

/// Environment variable carrying a child's launch name (its node name and log prefix).
pub const PROCESS_NAME_ENV: &str = "HARVEST_PROCESS_NAME";

/// Starts `spec` as `executable <command> <args>` (or as `spec.executable <args>` when the
/// launch file names a program) in its own process group (so a terminal's
/// Ctrl-C reaches only the supervisor, which then stops children in order), with the parent-death
/// signal set so children never outlive a killed supervisor. The child keeps `domain_lock_fd`
/// open across exec ([`crate::domain_lock::DomainLock::inheritable_fd`]): the domain stays held
/// until the last process of the stack is gone.
///
/// The control token goes to every child in `HARVEST_CONTROL_TOKEN` (the executive checks
/// operator commands with it; the others ignore it).
///
/// The launch file's scheduling settings ([`crate::scheduling`]) are applied in the child before
/// `exec`; what the kernel granted comes back with the child. A refused setting does not stop
/// the start.
pub fn spawn(
    executable: &Path,
    spec: &ProcessSpec,
    domain: &Domain,
    domain_lock_fd: RawFd,
    control_token: &str,
) -> std::io::Result<(Child, SchedulingOutcome)> {
    let mut command = match &spec.executable {
        Some(program) => Command::new(program),
        None => {
            let mut command = Command::new(executable);
            command.arg(&spec.command);
            command
        }
    };
    command
        .args(&spec.args)
        .env(harvest_ipc::domain::DOMAIN_ENV, domain.name())
        .env(PROCESS_NAME_ENV, &spec.name)
        .env(harvest_operator::token::CONTROL_TOKEN_ENV, control_token)
        .process_group(0);
    // SAFETY: the closure runs in the forked child before exec and only calls prctl and fcntl,
    // which are async-signal-safe. Clearing FD_CLOEXEC changes the child's descriptor table only.
    unsafe {
        command.pre_exec(move || {
            nix::sys::prctl::set_pdeathsig(Some(Signal::SIGTERM)).map_err(std::io::Error::from)?;
            if nix::libc::fcntl(domain_lock_fd, nix::libc::F_SETFD, 0) == -1 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    if spec.scheduling.is_default() {
        return Ok((command.spawn()?, SchedulingOutcome::none()));
    }
    if spec.scheduling.lock_memory {
        command.env(harvest_ipc::memory_lock::LOCK_MEMORY_ENV, "1");
    }
    let prepared = spec.scheduling.prepare();
    let pipe = OutcomePipe::new()?;
    let outcome_fd = pipe.write_fd();
    // SAFETY: the closure runs in the forked child before exec and only makes the
    // async-signal-safe calls of `PreparedScheduling::apply_in_child` (no allocation).
    unsafe {
        command.pre_exec(move || {
            prepared.apply_in_child(outcome_fd);
            Ok(())
        });
    }
    let child = command.spawn()?;
    Ok((child, pipe.read_outcome(&spec.scheduling)))
}

/// Sends `signal` to the child's whole process group.
pub fn signal_group(child: &Child, signal: Signal) {
    let pid = Pid::from_raw(child.id() as i32);
    if let Err(error) = killpg(pid, signal) {
        tracing::debug!(pid = child.id(), ?signal, %error, "signal failed (already gone?)");
    }
}
