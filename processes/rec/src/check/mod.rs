//! `harvest replay --check FILE...`: this build's nodes re-run on a recording's inputs, on the
//! recorded clock, and each output compared with the one recorded ([`perception_rerun`] for
//! what is re-run and how; [`json_diff`] for the comparison). Two runs on one file print the
//! same report byte for byte; the speed goes to the log.

pub mod control_nodes;
pub mod control_rerun;
pub mod held_sample;
pub mod json_diff;
pub mod monitor_rejudge;
pub mod perception_rerun;
pub mod recorded_devices;
pub mod recorded_inputs;
pub mod report;
pub mod scan_recording;

use std::path::PathBuf;

use harvest_perception::task::PerceptionTask;

pub use control_nodes::{arm_rerun, vacuum_rerun};
pub use control_rerun::{ControlCheck, ControlNode, ControlRerun};
pub use perception_rerun::PerceptionCheck;
pub use recorded_devices::{RecordedBoard, RecordedServos};
pub use report::{ChannelCheck, CheckError};

/// What `harvest replay --check` re-ran and found.
pub struct CheckReport {
    /// Perception's re-run, or why the recording does not allow one (e.g. the camera recorded
    /// as H.264 video).
    pub perception: Result<PerceptionCheck, String>,
    /// The control nodes whose tick records the recording holds.
    pub controls: Vec<ControlCheck>,
    /// The control nodes not re-run, and why (no tick records; none from the process's start).
    pub controls_absent: Vec<(&'static str, String)>,
    /// The wall time of the pass that read the control nodes' records and messages.
    pub controls_read_wall_s: f64,
    /// The safety monitor's findings re-judged (`None`: the live monitor published none, as
    /// with `--on-violation print`).
    pub monitor: Option<ChannelCheck>,
}

impl CheckReport {
    pub fn channels(&self) -> impl Iterator<Item = &ChannelCheck> {
        self.perception
            .iter()
            .flat_map(|perception| [&perception.detections, &perception.scan_requests])
            .chain(self.controls.iter().flat_map(|control| &control.channels))
            .chain(self.monitor.iter())
    }

    /// Whether any re-run output differs from the recording.
    pub fn differs(&self) -> bool {
        self.channels().any(ChannelCheck::differs)
    }

    /// The wall time every re-run took (the control nodes' reading pass included).
    pub fn rerun_wall_s(&self) -> f64 {
        self.perception
            .as_ref()
            .map_or(0.0, |perception| perception.rerun_wall_s)
            + self.controls_wall_s()
    }

    /// The recorded time covered, s.
    pub fn recorded_span_s(&self) -> f64 {
        let perception = self
            .perception
            .as_ref()
            .map_or(0, |perception| perception.recorded_span_ns);
        let controls = self.controls.iter().map(|control| control.recorded_span_ns);
        controls.fold(perception, u64::max) as f64 * 1e-9
    }

    /// The wall time of the control nodes' pass: reading the recording, then every re-run.
    pub fn controls_wall_s(&self) -> f64 {
        self.controls_read_wall_s
            + self
                .controls
                .iter()
                .map(|control| control.rerun_wall_s)
                .sum::<f64>()
    }
}

impl std::fmt::Display for CheckReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.perception {
            Ok(perception) => {
                writeln!(f, "check: perception re-run on the recorded frames")?;
                write!(f, "{}", perception.detections)?;
                write!(f, "{}", perception.scan_requests)?;
            }
            Err(reason) => writeln!(f, "check: perception not re-run: {reason}")?,
        }
        for control in &self.controls {
            write!(f, "{control}")?;
        }
        match &self.monitor {
            Some(monitor) => {
                writeln!(
                    f,
                    "check: the safety monitor's rules re-judged on the recording"
                )?;
                write!(f, "{monitor}")?;
            }
            None => writeln!(
                f,
                "check: the safety monitor not re-judged (it published nothing live: --monitor-on-violation print)"
            )?,
        }
        for (name, reason) in &self.controls_absent {
            writeln!(f, "check: {name} not re-run: {reason}")?;
        }
        if self.differs() {
            writeln!(f, "check: DIFFERENT")
        } else {
            writeln!(f, "check: identical")
        }
    }
}

/// Re-runs `perception` (built from the live process's arguments) and the control nodes on
/// `files`, segments of one recording in order, and compares the safety monitor's findings
/// re-judged on them (`monitor`: the messages this build's monitor would have published;
/// `None` when the live monitor published none); `tolerance`: absolute, for floats (exact
/// when `None`). A node the recording does not allow re-running is reported as such; a
/// recording that allows none is an error.
pub fn run_check(
    files: &[PathBuf],
    perception: PerceptionTask,
    controls: &[Box<dyn ControlRerun>],
    monitor: Option<&[harvest_ipc::payloads::SafetyViolation]>,
    tolerance: Option<f64>,
) -> Result<CheckReport, CheckError> {
    let perception = match perception_rerun::check_perception(files, perception, tolerance) {
        Ok(check) => Ok(check),
        Err(CheckError::NothingToCheck(reason)) => Err(reason),
        Err(error) => return Err(error),
    };
    let reading = std::time::Instant::now();
    let recorded = control_rerun::read_recording(files, controls)?;
    let mut report = CheckReport {
        perception,
        controls: Vec::new(),
        controls_absent: Vec::new(),
        controls_read_wall_s: reading.elapsed().as_secs_f64(),
        monitor: monitor.map(|rejudged| {
            monitor_rejudge::check_violations(
                &recorded.violations,
                recorded.first_log_time_ns.unwrap_or_default(),
                rejudged,
                tolerance,
            )
        }),
    };
    for control in controls {
        match control.rerun(&recorded, tolerance)? {
            Some(check) if check.ticks_rerun > 0 => report.controls.push(check),
            Some(check) => report.controls_absent.push((
                control.name(),
                format!(
                    "none of its {} recorded ticks follows a start of the process (tick 1): record from the start",
                    check.ticks_before_start
                ),
            )),
            None => report.controls_absent.push((
                control.name(),
                "the recording holds none of its tick records".to_owned(),
            )),
        }
    }
    if let (Err(reason), true) = (&report.perception, report.controls.is_empty()) {
        return Err(CheckError::NothingToCheck(format!(
            "{reason}; and no control node's tick records"
        )));
    }
    Ok(report)
}
