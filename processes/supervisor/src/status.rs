//! The supervisor's view of each process, its live status lines and the final summary.

use harvest_ipc::payloads::{DeviceErrorCode, ProcessRunState};
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
    /// The kind of the last device error the process reported in its heartbeat
    /// ([`DeviceErrorCode::None`]: none; kept across a restart, like the restart count).
    pub last_device_error: DeviceErrorCode,
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
        if let Some(label) = self.device_error_label() {
            parts.push(label);
        }
        if !self.scheduling.is_empty() {
            parts.push(format!("[{}]", self.scheduling));
        }
        parts.join("  ")
    }
}

impl ProcessStatus {
    /// `device error: timeout` (the kind of the last device error), `None` without one.
    pub fn device_error_label(&self) -> Option<String> {
        (self.last_device_error != DeviceErrorCode::None)
            .then(|| format!("device error: {}", self.last_device_error))
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

#[cfg(test)]
mod tests {
    use super::*;

    fn running() -> ProcessStatus {
        ProcessStatus {
            name: "vacuum".to_owned(),
            phase: ProcessPhase::Running { pid: 42 },
            restarts: 0,
            last_exit: None,
            main_channel_count: 0,
            main_channel_rate_hz: 0.0,
            detail: "period_p99_us".to_owned(),
            detail_value: 5012,
            deadline_misses: 0,
            scheduling: String::new(),
            run_state: Some(ProcessRunState::Degraded),
            critical: true,
            last_device_error: DeviceErrorCode::None,
        }
    }

    #[test]
    fn the_status_line_names_the_kind_of_the_last_device_error() {
        let mut status = running();
        assert!(!render(&[status.clone()], 1.0).contains("device error"));
        status.last_device_error = DeviceErrorCode::Disconnected;
        let line = render(&[status], 1.0);
        assert!(line.contains("DEGRADED pid 42"), "{line}");
        assert!(line.contains("device error: disconnected"), "{line}");
    }
}
