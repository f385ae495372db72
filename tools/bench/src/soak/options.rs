//! Command-line options of `harvest soak`.

use harvest_ipc::duration::parse_duration;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Duration;

use super::error::SoakError;

/// `harvest soak`: the default stack (`harvest up`, embedded default launch file) in a domain of
/// its own for `--duration`, with seeded random SIGKILLs of its processes, operator commands
/// through `harvest ctl`, bad inputs on the operator and shared channels, and samples of every
/// process's memory and descriptors and of the domain's shared-memory files; prints a report
/// with verdicts (exit 1 when one fails).
#[derive(Debug, Clone, clap::Args)]
pub struct SoakArgs {
    /// How long the stack runs, e.g. `30m`, `40s`
    #[arg(long, value_parser = parse_duration, default_value = "30m")]
    pub duration: Duration,
    /// Seed of the schedule (kills, operator scenarios, bad inputs)
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Mean time between two SIGKILLs of a random stack process (uniform in 0.5x-1.5x)
    #[arg(long, value_parser = parse_duration, default_value = "2m")]
    pub kill_every: Duration,
    /// Stop killing after this many kills (default: no limit)
    #[arg(long)]
    pub max_kills: Option<u32>,
    /// Mean time between two operator scenarios (pause/resume, stop/home/start,
    /// estop/release/start, arm disable/enable, status)
    #[arg(long, value_parser = parse_duration, default_value = "45s")]
    pub ctl_every: Duration,
    /// Mean time between two bad inputs (wrong token, jog past the limits, garbage on
    /// `operator/command`, `harvest/events`, `system/health`)
    #[arg(long, value_parser = parse_duration, default_value = "30s")]
    pub bad_input_every: Duration,
    /// Time between two samples of RSS, descriptors and shared-memory files
    #[arg(long, value_parser = parse_duration, default_value = "5s")]
    pub sample_every: Duration,
    /// Nothing is killed, commanded or fed during the first part of the run (start-up)
    #[arg(long, value_parser = parse_duration, default_value = "10s")]
    pub warmup: Duration,
    /// Once the vacuum supervisor reports nothing left to pick, wait this long, then replant:
    /// SIGKILL the simulator and the vacuum supervisor and remove the simulator's world state
    /// file, so the restarted simulator regenerates the scenario's apples and harvesting goes
    /// on (`0s`: never replant)
    #[arg(long, value_parser = parse_duration, default_value = "5s")]
    pub replant_after: Duration,
    /// Memory growth bound: least-squares slope of a process's private resident memory
    /// (`RssAnon`: heap, stacks) over the second half of the run, KiB per minute, beyond which
    /// the verdict fails. Shared-memory pages a process touches (`RssShmem`) are reported, not
    /// judged: they are bounded by the segments it maps
    /// (the domain's files, judged on their own)
    #[arg(long, default_value_t = 128.0)]
    pub rss_slope_bound_kib_per_min: f64,
    /// Descriptor growth bound: slope of a process's open descriptors over the second half,
    /// per minute
    #[arg(long, default_value_t = 0.2)]
    pub fd_slope_bound_per_min: f64,
    /// Shared-memory growth bound: slope of the domain's shared-memory files over the second
    /// half, per minute
    #[arg(long, default_value_t = 1.0)]
    pub shm_slope_bound_per_min: f64,
    /// Write the report with every sample as JSON to this file
    #[arg(long, value_name = "PATH")]
    pub out: Option<PathBuf>,
    /// Keep the run's scratch directory (launch copy, stack logs, recordings)
    #[arg(long)]
    pub keep_files: bool,
    /// The `harvest` executable that runs the stack and `harvest ctl` [default: this
    /// executable]
    #[arg(long, value_name = "PATH", hide = true)]
    pub harvest_exe: Option<PathBuf>,
}

/// The bounds the verdicts judge against (as given on the command line).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Bounds {
    pub rss_slope_kib_per_min: f64,
    pub fd_slope_per_min: f64,
    pub shm_slope_per_min: f64,
}

impl SoakArgs {
    /// Rejects values the run cannot honour, naming the option.
    pub fn validate(&self) -> Result<(), SoakError> {
        let positive = [
            ("duration", self.duration),
            ("kill-every", self.kill_every),
            ("ctl-every", self.ctl_every),
            ("bad-input-every", self.bad_input_every),
            ("sample-every", self.sample_every),
        ];
        for (option, value) in positive {
            if value.is_zero() {
                return Err(SoakError::InvalidOption {
                    option,
                    value: "0".to_owned(),
                    reason: "must be positive".to_owned(),
                });
            }
        }
        if self.warmup >= self.duration {
            return Err(SoakError::InvalidOption {
                option: "warmup",
                value: format!("{:?}", self.warmup),
                reason: format!("must be shorter than --duration {:?}", self.duration),
            });
        }
        let bounds = [
            (
                "rss-slope-bound-kib-per-min",
                self.rss_slope_bound_kib_per_min,
            ),
            ("fd-slope-bound-per-min", self.fd_slope_bound_per_min),
            ("shm-slope-bound-per-min", self.shm_slope_bound_per_min),
        ];
        for (option, value) in bounds {
            if !(value.is_finite() && value >= 0.0) {
                return Err(SoakError::InvalidOption {
                    option,
                    value: value.to_string(),
                    reason: "must be a finite number >= 0".to_owned(),
                });
            }
        }
        Ok(())
    }

    pub fn bounds(&self) -> Bounds {
        Bounds {
            rss_slope_kib_per_min: self.rss_slope_bound_kib_per_min,
            fd_slope_per_min: self.fd_slope_bound_per_min,
            shm_slope_per_min: self.shm_slope_bound_per_min,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: SoakArgs,
    }

    #[test]
    fn defaults_parse_and_validate() {
        let cli = Cli::try_parse_from(["x"]).expect("parses");
        assert_eq!(cli.args.duration, Duration::from_secs(1800));
        cli.args.validate().expect("valid defaults");
        let cli =
            Cli::try_parse_from(["x", "--duration", "40s", "--max-kills", "1"]).expect("parses");
        assert_eq!(cli.args.max_kills, Some(1));
    }

    #[test]
    fn bad_values_name_the_option() {
        let cli = Cli::try_parse_from(["x", "--duration", "5s"]).expect("parses");
        let error = cli
            .args
            .validate()
            .expect_err("warm-up longer than the run");
        assert!(error.to_string().contains("--warmup"), "{error}");
        let cli = Cli::try_parse_from(["x", "--kill-every", "0s"]).expect("parses");
        let error = cli.args.validate().expect_err("zero period");
        assert!(error.to_string().contains("--kill-every"), "{error}");
        let cli = Cli::try_parse_from(["x", "--rss-slope-bound-kib-per-min=-1"]).expect("parses");
        assert!(cli.args.validate().is_err());
    }
}
