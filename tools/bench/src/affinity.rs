//! Pinning a process to a CPU (`sched_setaffinity`), and restoring its previous CPU set.

use crate::error::BenchError;
use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
use nix::unistd::Pid;

/// Restricts the calling process (all its future threads) to `cpu`.
pub fn pin_to_cpu(cpu: usize) -> Result<(), BenchError> {
    let mut set = CpuSet::new();
    set.set(cpu)
        .map_err(|source| BenchError::Affinity { cpu, source })?;
    sched_setaffinity(Pid::from_raw(0), &set).map_err(|source| BenchError::Affinity { cpu, source })
}

/// The calling process's CPU set before pinning; restores it when dropped.
pub struct AffinityRestore {
    previous: CpuSet,
}

impl AffinityRestore {
    /// Pins the calling process to `cpu`, remembering its CPU set.
    pub fn pin(cpu: usize) -> Result<Self, BenchError> {
        let previous = sched_getaffinity(Pid::from_raw(0))
            .map_err(|source| BenchError::Affinity { cpu, source })?;
        pin_to_cpu(cpu)?;
        Ok(Self { previous })
    }
}

impl Drop for AffinityRestore {
    fn drop(&mut self) {
        if let Err(error) = sched_setaffinity(Pid::from_raw(0), &self.previous) {
            tracing::warn!(%error, "cannot restore the CPU affinity after the benchmark");
        }
    }
}
