//! `harvest replay --check FILE...`: this build's nodes re-run on a recording's inputs, on the
//! recorded clock, and each output compared with the one recorded ([`perception_rerun`] for
//! what is re-run and how; [`json_diff`] for the comparison). Two runs on one file print the
//! same report byte for byte; the speed goes to the log.

pub mod held_sample;
pub mod json_diff;
pub mod perception_rerun;
pub mod recorded_inputs;
pub mod report;

use std::path::PathBuf;

use harvest_perception::task::PerceptionTask;

pub use perception_rerun::PerceptionCheck;
pub use report::{ChannelCheck, CheckError};

/// What `harvest replay --check` re-ran and found.
pub struct CheckReport {
    pub perception: PerceptionCheck,
}

impl CheckReport {
    pub fn channels(&self) -> [&ChannelCheck; 2] {
        [&self.perception.detections, &self.perception.scan_requests]
    }

    /// Whether any re-run output differs from the recording.
    pub fn differs(&self) -> bool {
        self.channels().iter().any(|channel| channel.differs())
    }

    /// Recorded time re-run per second of wall time.
    pub fn speed_factor(&self) -> f64 {
        let span_s = self.perception.recorded_span_ns as f64 * 1e-9;
        if self.perception.rerun_wall_s > 0.0 {
            span_s / self.perception.rerun_wall_s
        } else {
            0.0
        }
    }
}

impl std::fmt::Display for CheckReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "check: perception re-run on the recorded frames")?;
        for channel in self.channels() {
            write!(f, "{channel}")?;
        }
        if self.differs() {
            writeln!(f, "check: DIFFERENT")
        } else {
            writeln!(f, "check: identical")
        }
    }
}

/// Re-runs `perception` (built from the live process's arguments) on `files`, segments of one
/// recording in order; `tolerance`: absolute, for floats (exact when `None`).
pub fn run_check(
    files: &[PathBuf],
    perception: PerceptionTask,
    tolerance: Option<f64>,
) -> Result<CheckReport, CheckError> {
    let perception = perception_rerun::check_perception(files, perception, tolerance)?;
    let report = CheckReport { perception };
    tracing::info!(
        recorded_s = report.perception.recorded_span_ns as f64 * 1e-9,
        wall_s = report.perception.rerun_wall_s,
        speed = report.speed_factor(),
        "check done"
    );
    Ok(report)
}
