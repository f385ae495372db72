//! Locking a control-loop process's memory into RAM (`mlockall`), asked for by its launch file.
//!
//! A memory lock does not survive `exec`, so the supervisor cannot lock a child's memory for it:
//! it sets [`LOCK_MEMORY_ENV`] (`scheduling.lock_memory = true` in the launch file) and the
//! process locks itself once everything its loop touches exists ([`lock_if_requested`], called
//! by [`crate::control_loop::run_control_loop`] after the ports, the node and the period
//! histogram are built, just before the first tick). `MCL_CURRENT` faults in and locks every
//! page mapped so far (heap, shared-memory channels, code); `MCL_FUTURE` locks whatever is
//! mapped later as it is mapped; the stack the loop will use is touched once
//! ([`STACK_PREFAULT_BYTES`]) so that no page fault happens inside a tick.

/// Set to `1` by the supervisor for a process whose launch entry asks for `lock_memory`.
pub const LOCK_MEMORY_ENV: &str = "HARVEST_LOCK_MEMORY";

/// Stack faulted in before the loop, bytes (the loop's deepest call chain, the node's step
/// with the kinematics and the clearance check, uses far less).
pub const STACK_PREFAULT_BYTES: usize = 256 * 1024;

/// What became of the memory lock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MemoryLock {
    /// The launch file did not ask for it ([`LOCK_MEMORY_ENV`] unset).
    NotRequested,
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)` succeeded; `locked_kib` is the kernel's `VmLck`.
    Locked {
        /// Memory locked, KiB (`VmLck` of `/proc/self/status`).
        locked_kib: u64,
    },
    /// The kernel refused (`EPERM` without `CAP_IPC_LOCK`, `ENOMEM` beyond `RLIMIT_MEMLOCK`):
    /// the process runs unlocked.
    Refused {
        /// The error `mlockall` returned.
        errno: nix::errno::Errno,
    },
}

/// Whether this process was asked to lock its memory.
pub fn requested() -> bool {
    std::env::var_os(LOCK_MEMORY_ENV).is_some_and(|value| value == "1")
}

/// Locks all current and future memory and faults in the loop's stack, if [`requested`].
/// Logs the outcome (a refusal is a warning: the process runs anyway).
pub fn lock_if_requested() -> MemoryLock {
    if !requested() {
        return MemoryLock::NotRequested;
    }
    use nix::sys::mman::{MlockAllFlags, mlockall};
    let outcome = match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
        Ok(()) => {
            prefault_stack();
            MemoryLock::Locked {
                locked_kib: locked_kib(std::process::id()).unwrap_or(0),
            }
        }
        Err(errno) => MemoryLock::Refused { errno },
    };
    match &outcome {
        MemoryLock::Locked { locked_kib } => {
            tracing::info!(
                locked_kib,
                "memory locked (mlockall), loop stack faulted in"
            );
        }
        MemoryLock::Refused { errno } => tracing::warn!(
            %errno,
            "memory lock refused (needs CAP_IPC_LOCK or a large enough LimitMEMLOCK): running \
             unlocked, page faults may stall the loop"
        ),
        MemoryLock::NotRequested => {}
    }
    outcome
}

/// `VmLck` of process `pid` (KiB), from `/proc/<pid>/status`; None if unreadable.
pub fn locked_kib(pid: u32) -> Option<u64> {
    crate::proc_status::process_status_field(pid, "VmLck:")
}

/// Touches [`STACK_PREFAULT_BYTES`] of stack below the caller, so that under `MCL_FUTURE` those
/// pages are mapped and locked before the loop runs.
#[inline(never)]
fn prefault_stack() {
    let mut stack = [0u8; STACK_PREFAULT_BYTES];
    // Writing through `black_box` keeps the compiler from eliding the array.
    std::hint::black_box(&mut stack)[STACK_PREFAULT_BYTES - 1] = 1;
    std::hint::black_box(&stack);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn not_requested_without_the_variable() {
        // The test runner does not set it (and tests must not lock the runner's memory).
        if std::env::var_os(LOCK_MEMORY_ENV).is_none() {
            assert_eq!(lock_if_requested(), MemoryLock::NotRequested);
        }
    }

    #[test]
    fn reads_the_locked_size_of_a_process() {
        assert!(locked_kib(std::process::id()).is_some());
        assert_eq!(locked_kib(u32::MAX), None);
    }
}
