//! Command line of `harvest monitor`.

use std::path::PathBuf;
use std::time::Duration;

use harvest_ipc::Domain;
use harvest_safety::safety_monitor::MonitorConfig;

use crate::error::MonitorError;
use crate::live::{LiveOptions, run_live};
use crate::mapping::{DEFAULT_ATTACH_WINDOW_NS, MappingConfig, STACK_REACTION_NS};
use crate::recording::check_recording;
use crate::stack_monitor::MonitorReport;
use crate::violation_message::OnViolation;

/// Arguments of `harvest monitor`.
#[derive(Debug, Clone, clap::Args)]
pub struct MonitorArgs {
    /// Judge this MCAP recording instead of the live stack.
    #[arg(long)]
    pub recording: Option<PathBuf>,
    /// Stop the live monitor after this long (e.g. 30s, 2m); default: until Ctrl-C.
    #[arg(long, value_parser = harvest_ipc::duration::parse_duration)]
    pub duration: Option<Duration>,
    /// An open valve without a seal for longer than this is a failed attachment, ms.
    #[arg(long, default_value_t = DEFAULT_ATTACH_WINDOW_NS / 1_000_000)]
    pub attach_window_ms: u64,
    /// Deadline to close a valve after a failure or an emergency stop, as seen on the
    /// channels, ms.
    #[arg(long, default_value_t = STACK_REACTION_NS / 1_000_000)]
    pub reaction_ms: u64,
    /// Minimum distance between the two end-effectors, m.
    #[arg(long, default_value_t = 0.10)]
    pub clearance_m: f64,
    /// Live only: ask the executive for the protective stop (on `safety/violation`) this long
    /// after starting (e.g. 15s) and report how long the stack takes to close every valve and
    /// brake both arms. The stop stays engaged until an operator releases it.
    #[arg(long, value_parser = harvest_ipc::duration::parse_duration)]
    pub engage_stop_after: Option<Duration>,
    /// Live only: what to do with a violation besides printing it: `print` (nothing more),
    /// `report` (publish it on `safety/violation`), `stop` (publish it and have the executive
    /// engage the protective stop). The default launch file runs `stop`.
    #[arg(long, value_enum, default_value = "print")]
    pub on_violation: OnViolation,
}

impl Default for MonitorArgs {
    fn default() -> Self {
        Self {
            recording: None,
            duration: None,
            attach_window_ms: DEFAULT_ATTACH_WINDOW_NS / 1_000_000,
            reaction_ms: STACK_REACTION_NS / 1_000_000,
            clearance_m: 0.10,
            engage_stop_after: None,
            on_violation: OnViolation::Print,
        }
    }
}

impl MonitorArgs {
    /// The rules' settings these arguments give.
    pub fn configs(&self) -> Result<(MappingConfig, MonitorConfig), MonitorError> {
        if self.reaction_ms == 0 {
            return Err(MonitorError::InvalidArgument {
                arg: "--reaction-ms",
                value: "0".to_owned(),
                reason: "must be > 0",
            });
        }
        if !(self.clearance_m.is_finite() && self.clearance_m >= 0.0) {
            return Err(MonitorError::InvalidArgument {
                arg: "--clearance-m",
                value: self.clearance_m.to_string(),
                reason: "must be finite and >= 0",
            });
        }
        Ok((
            MappingConfig {
                attach_window_ns: self.attach_window_ms * 1_000_000,
                ..MappingConfig::default()
            },
            MonitorConfig {
                control_period_ns: self.reaction_ms * 1_000_000,
                clearance_m: self.clearance_m,
            },
        ))
    }
}

/// Runs `harvest monitor`: prints each violation as it is found (on stdout) and returns the
/// report (the caller prints the summary and exits non-zero when there are violations).
pub fn run_monitor(
    args: &MonitorArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<MonitorReport, MonitorError> {
    let (mapping, checks) = args.configs()?;
    let print = |v: &harvest_safety::safety_monitor::Violation| println!("VIOLATION {v}");
    match &args.recording {
        Some(_) if args.engage_stop_after.is_some() => Err(MonitorError::InvalidArgument {
            arg: "--engage-stop-after",
            value: format!("{:?}", args.engage_stop_after),
            reason: "only for the live stack, not with --recording",
        }),
        Some(_) if args.on_violation != OnViolation::Print => Err(MonitorError::InvalidArgument {
            arg: "--on-violation",
            value: format!("{:?}", args.on_violation),
            reason: "only for the live stack, not with --recording",
        }),
        Some(path) => check_recording(path, mapping, checks, print),
        None => run_live(
            domain,
            process_name,
            LiveOptions {
                duration: args.duration,
                engage_stop_after: args.engage_stop_after,
                on_violation: args.on_violation,
            },
            mapping,
            checks,
            print,
        ),
    }
}
