//! The supervisor's view of each process, its live status lines and the final summary.

use harvest_ipc::payloads::ProcessRunState;
use std::fmt::Write as _;
use std::time::Instant;

/// Where one process stands.
#[derive(Debug, Clone, PartialEq)]
pub enum ProcessPhase {
    Running { pid: u32 },
    WaitingToRestart { until: Instant },
    Finished,
    FailedForGood { reason: String },
    Stopped,
}

/// Everything the supervisor tracks about one process.
#[derive(Debug, Clone)]
pub struct ProcessStatus {
    pub name: String,
    pub phase: ProcessPhase,
    pub restarts: u32,
    pub last_exit: Option<String>,
    pub main_channel_count: u64,
    pub main_channel_rate_hz: f64,
    pub detail: String,
    pub detail_value: u64,
    /// Control loops: deadline misses so far (from the heartbeat).
    pub deadline_misses: u64,
    /// What the launch file's scheduling settings became (`fifo80 cpu1 mlock 41MiB`; refused
    /// parts marked `:EPERM`); empty when none were asked.
    pub scheduling: String,
    /// The run state of the process's last heartbeat (None before the first one).
    pub run_state: Option<ProcessRunState>,
    /// Failing for good stops the stack (the launch file's `critical`).
    pub critical: bool,
}

impl ProcessStatus {
    pub fn state_label(&self) -> String {
        match &self.phase {
            ProcessPhase::Running { pid } => match self.run_state {
                Some(ProcessRunState::Degraded) => format!("DEGRADED pid {pid}"),
                _ => format!("running pid {pid}"),
            },
            ProcessPhase::WaitingToRestart { until } => {
                let wait = until.saturating_duration_since(Instant::now());
                format!("restart in {:.1}s", wait.as_secs_f64())
            }
            ProcessPhase::Finished => "finished".to_owned(),
            ProcessPhase::FailedForGood { .. } if self.critical => "FAILED".to_owned(),
            ProcessPhase::FailedForGood { .. } => "FAILED:noncritical".to_owned(),
            ProcessPhase::Stopped => "stopped".to_owned(),
        }
    }
}

impl ProcessStatus {
    /// The heartbeat's figure, the deadline misses and the scheduling, as shown after the rate.
    pub fn detail_label(&self) -> String {
        let mut parts = Vec::new();
        if !self.detail.is_empty() {
            parts.push(format!("{} {}", self.detail, self.detail_value));
        }
        if self.deadline_misses > 0 {
            parts.push(format!("deadline misses {}", self.deadline_misses));
        }
        if !self.scheduling.is_empty() {
            parts.push(format!("[{}]", self.scheduling));
        }
        parts.join("  ")
    }
}

/// One line per process: name, state, restarts, main-channel rate, detail.
pub fn render(statuses: &[ProcessStatus], elapsed_s: f64) -> String {
    let mut out = format!("harvest up: {elapsed_s:.0}s\n");
    for status in statuses {
        let _ = writeln!(
            out,
            "  {:<12} {:<18} restarts {:<2} {:>7.1} msg/s  {}",
            status.name,
            status.state_label(),
            status.restarts,
            status.main_channel_rate_hz,
            status.detail_label()
        );
    }
    out
}
