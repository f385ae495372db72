//! The one way a process learns it should stop: SIGINT or SIGTERM set a flag that stays set.
//!
//! Every loop of the stack ends through it:
//! - wait-set loops run [`crate::Waiter::run`], which installs the handler, wakes when a signal
//!   interrupts its wait (`epoll_wait`/`select` return `EINTR` whatever `SA_RESTART` says) and
//!   returns [`crate::RunEnd::Signal`] once [`requested`] is true;
//! - loops that block on a device instead (a camera driver in its capture call with a timeout,
//!   replay pacing its messages) call [`install_handler`] once and test [`requested`] each turn.
//!
//! iceoryx2 has a signal handler of its own (`iceoryx2_bb_posix::signal::SignalHandler`): it
//! takes over SIGINT, SIGTERM and ten other signals the first time anything uses it (a wait set
//! or a node in `SignalHandlingMode::HandleTerminationRequests`, zero-filling shared memory),
//! and its "last signal" slot is consumed by whoever reads it first. The stack therefore runs
//! its wait sets and nodes with `SignalHandlingMode::Disabled`, and [`install_handler`] lets
//! iceoryx2 install its handlers first so that ours, installed over them for SIGINT and
//! SIGTERM, stays in place for the life of the process. A side effect, as in every wait-set
//! process before: iceoryx2's handlers catch the other signals it fetches (SIGTSTP, SIGQUIT,
//! SIGUSR1, ...), so Ctrl-Z does not suspend a stack process.
//!
//! A signal is seen at the latest when the loop next wakes: a signal delivered to another
//! thread does not interrupt the loop's wait, so loops attach an interval (heartbeats do).

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

static TERMINATION_REQUESTED: AtomicBool = AtomicBool::new(false);
static INSTALLED: Mutex<bool> = Mutex::new(false);

extern "C" fn on_termination_signal(_signal: i32) {
    TERMINATION_REQUESTED.store(true, Ordering::SeqCst);
}

/// Installs the handler for SIGINT and SIGTERM (idempotent; see the module docs).
pub fn install_handler() -> Result<(), std::io::Error> {
    use nix::sys::signal::{SaFlags, SigAction, SigHandler, SigSet, Signal, sigaction};
    // A poisoned lock only means another thread panicked while installing: install again.
    let mut installed = INSTALLED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if *installed {
        return Ok(());
    }
    // Make iceoryx2 install its handlers now, so it never replaces ours later.
    let _ = iceoryx2_bb_posix::signal::SignalHandler::call_and_fetch(|| {});
    let action = SigAction::new(
        SigHandler::Handler(on_termination_signal),
        SaFlags::SA_RESTART,
        SigSet::empty(),
    );
    for signal in [Signal::SIGINT, Signal::SIGTERM] {
        // SAFETY: the handler only stores to an atomic, which is async-signal-safe.
        unsafe { sigaction(signal, &action) }.map_err(std::io::Error::from)?;
    }
    *installed = true;
    Ok(())
}

/// True once SIGINT or SIGTERM arrived (after [`install_handler`]).
pub fn requested() -> bool {
    TERMINATION_REQUESTED.load(Ordering::SeqCst)
}
