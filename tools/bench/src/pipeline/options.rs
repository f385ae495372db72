//! Command-line options of `harvest bench pipeline`.

use crate::error::BenchError;
use harvest_ipc::duration::parse_duration;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Duration;

/// `harvest bench pipeline`: end-to-end latency in a running stack on the simulated robot,
/// camera capture -> camera -> perception -> vacuum's arm target -> arm command, per hop from
/// the message headers, and the arm control loop's period jitter.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct BenchPipelineArgs {
    /// How long to collect after the warm-up, e.g. `20s` [default: 20s]
    #[arg(long, value_parser = parse_duration)]
    pub duration: Option<Duration>,
    /// Time between the stack's start (or, with --attach, the bench's) and the start of
    /// collecting: process start-up and the first frames are not measured [default: 5s]
    #[arg(long, value_parser = parse_duration)]
    pub warmup: Option<Duration>,
    /// Launch file of the stack the bench starts [default: the bench's embedded launch file:
    /// sim, camera, perception, vacuum, arm1, arm2]
    #[arg(long, value_name = "PATH", conflicts_with = "attach")]
    pub launch: Option<PathBuf>,
    /// Measure the stack already running in --domain instead of starting one in a domain of
    /// its own
    #[arg(long)]
    pub attach: bool,
    /// Write the report as JSON to this file
    #[arg(long, value_name = "PATH")]
    pub json: Option<PathBuf>,
    /// Write a per-hop latency plot (SVG) to this file
    #[arg(long, value_name = "PATH")]
    pub svg: Option<PathBuf>,
    /// Which runs to make: `both` (the launch file's `[process.scheduling]` settings, then the
    /// same stack with `harvest up --no-scheduling`, reported side by side), `launch` (as
    /// written) or `none` (without them). Ignored with --attach (one run of what is running)
    #[arg(long, value_enum, default_value_t = SchedulingRuns::Both)]
    pub scheduling: SchedulingRuns,
    /// Extra busy threads spinning at normal priority through the measured runs (a CPU hog
    /// beside the stack) [default: 0]
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub load: usize,
    /// The `harvest` executable that runs the stack [default: this executable]
    #[arg(long, value_name = "PATH", hide = true)]
    pub harvest_exe: Option<PathBuf>,
}

/// Which scheduling the bench's runs use.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SchedulingRuns {
    /// With the launch file's scheduling, then without, side by side.
    #[default]
    Both,
    /// The launch file as written.
    Launch,
    /// `harvest up --no-scheduling`.
    None,
}

/// The scheduling of one run of the stack.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunScheduling {
    /// The launch file's `[process.scheduling]` settings applied.
    AsLaunched,
    /// `harvest up --no-scheduling`.
    Without,
    /// A stack the bench did not start (--attach).
    Attached,
}

impl RunScheduling {
    pub fn label(self) -> &'static str {
        match self {
            Self::AsLaunched => "with the launch file's scheduling",
            Self::Without => "without scheduling (--no-scheduling)",
            Self::Attached => "attached (as running)",
        }
    }
}

impl SchedulingRuns {
    /// The runs to make, in order.
    pub fn runs(self, attached: bool) -> Vec<RunScheduling> {
        match (attached, self) {
            (true, _) => vec![RunScheduling::Attached],
            (false, Self::Both) => vec![RunScheduling::AsLaunched, RunScheduling::Without],
            (false, Self::Launch) => vec![RunScheduling::AsLaunched],
            (false, Self::None) => vec![RunScheduling::Without],
        }
    }
}

/// Resolved settings of a pipeline run.
#[derive(Debug, Clone, Serialize)]
pub struct PipelineSettings {
    #[serde(rename = "duration_s", serialize_with = "seconds")]
    pub duration: Duration,
    #[serde(rename = "warmup_s", serialize_with = "seconds")]
    pub warmup: Duration,
    /// The launch file used (`<embedded launch/pipeline.toml>` for the default), None with
    /// --attach.
    pub launch: Option<String>,
    pub attached: bool,
    /// Extra busy threads during the measured runs.
    pub load_threads: usize,
}

fn seconds<S: serde::Serializer>(value: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(value.as_secs_f64())
}

/// Shown for the embedded launch file.
pub const EMBEDDED_LAUNCH_NAME: &str = "<embedded processes/bench/launch/pipeline.toml>";

impl PipelineSettings {
    pub fn resolve(args: &BenchPipelineArgs) -> Result<Self, BenchError> {
        let duration = args.duration.unwrap_or(Duration::from_secs(20));
        if duration.is_zero() {
            return Err(BenchError::InvalidOption {
                option: "duration",
                value: "0".to_owned(),
                reason: "must be positive".to_owned(),
            });
        }
        Ok(Self {
            duration,
            warmup: args.warmup.unwrap_or(Duration::from_secs(5)),
            launch: match (&args.launch, args.attach) {
                (_, true) => None,
                (Some(path), false) => Some(path.display().to_string()),
                (None, false) => Some(EMBEDDED_LAUNCH_NAME.to_owned()),
            },
            attached: args.attach,
            load_threads: args.load,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_and_validation() {
        let settings = PipelineSettings::resolve(&BenchPipelineArgs::default()).expect("valid");
        assert_eq!(settings.duration, Duration::from_secs(20));
        assert_eq!(settings.warmup, Duration::from_secs(5));
        assert_eq!(settings.launch.as_deref(), Some(EMBEDDED_LAUNCH_NAME));
        let attached = BenchPipelineArgs {
            attach: true,
            duration: Some(Duration::from_secs(3)),
            ..BenchPipelineArgs::default()
        };
        let settings = PipelineSettings::resolve(&attached).expect("valid");
        assert!(settings.attached && settings.launch.is_none());
        let zero = BenchPipelineArgs {
            duration: Some(Duration::ZERO),
            ..BenchPipelineArgs::default()
        };
        assert!(matches!(
            PipelineSettings::resolve(&zero),
            Err(BenchError::InvalidOption {
                option: "duration",
                ..
            })
        ));
    }

    #[test]
    fn attach_and_launch_conflict_on_the_command_line() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            args: BenchPipelineArgs,
        }
        assert!(Cli::try_parse_from(["x", "--attach", "--launch", "a.toml"]).is_err());
        let cli =
            Cli::try_parse_from(["x", "--duration", "3s", "--warmup", "500ms"]).expect("parses");
        assert_eq!(cli.args.duration, Some(Duration::from_secs(3)));
        assert_eq!(cli.args.warmup, Some(Duration::from_millis(500)));
    }
}
