//! Command line of `harvest eval harvest`.

use std::path::PathBuf;

use serde::Serialize;

/// The coordination policy argument, shared with `harvest vacuum --policy`.
pub use harvest_vacuum_process::policy_arg::PolicyArg;

/// Which hardware timing the simulated robot runs with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
pub enum TimingArg {
    /// The scenario's own vacuum constants (gate travel, tube and source lags).
    Scenario,
    /// Fig. 12's phase times: gates and tube fast enough that attach + release take about
    /// 0.5 s, as in the paper's idealized analysis (see `timing.rs`).
    Fig12,
}

/// Arguments of `harvest eval harvest`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalHarvestArgs {
    /// Scenario preset (`ideal`, `default`, `gala_vertical_wall`, `fuji_ufo`) or TOML file.
    #[arg(long, default_value = "ideal")]
    pub scenario: String,
    /// Vacuum coordination policy.
    #[arg(long, value_enum, default_value = "2024")]
    pub policy: PolicyArg,
    /// Arms that harvest: 1 (arm 1 alone) or 2.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub arms: u8,
    /// World seed of the first episode; episode i uses seed + i.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Episodes (worlds) to run.
    #[arg(long, default_value_t = 1)]
    pub episodes: u32,
    /// Also write the report (summary, per-apple records, events) as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Hardware timing of the simulated robot.
    #[arg(long, value_enum, default_value = "scenario")]
    pub timing: TimingArg,
    /// Scale of the camera depth-noise model applied to the detections (0 = exact positions).
    #[arg(long, default_value_t = 1.0)]
    pub detection_noise: f64,
    /// Simulated time limit per episode, s.
    #[arg(long, default_value_t = 900.0)]
    pub max_episode_s: f64,
    /// Extra episodes that engage the emergency stop at staggered times (every phase of the
    /// cycle) to measure the reaction; 0 skips the measurement.
    #[arg(long, default_value_t = 20)]
    pub estop_trials: u32,
}

impl Default for EvalHarvestArgs {
    fn default() -> Self {
        Self {
            scenario: "ideal".to_owned(),
            policy: PolicyArg::V2024,
            arms: 2,
            seed: 1,
            episodes: 1,
            json: None,
            timing: TimingArg::Scenario,
            detection_noise: 1.0,
            max_episode_s: 900.0,
            estop_trials: 20,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use harvest_vacuum::policy::PolicyKind;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: EvalHarvestArgs,
    }

    #[test]
    fn defaults_and_values_parse() {
        let cli = Cli::try_parse_from(["x"]).expect("defaults");
        assert_eq!(cli.args.policy, PolicyArg::V2024);
        assert_eq!(cli.args.arms, 2);
        assert_eq!(cli.args.scenario, "ideal");
        let cli = Cli::try_parse_from([
            "x",
            "--policy",
            "2023",
            "--arms",
            "1",
            "--episodes",
            "3",
            "--timing",
            "fig12",
        ])
        .expect("values");
        assert_eq!(cli.args.policy.kind(), PolicyKind::V2023);
        assert_eq!((cli.args.arms, cli.args.episodes), (1, 3));
        assert_eq!(cli.args.timing, TimingArg::Fig12);
        assert!(Cli::try_parse_from(["x", "--arms", "3"]).is_err());
        assert!(Cli::try_parse_from(["x", "--policy", "2022"]).is_err());
        let cli = Cli::try_parse_from(["x", "--policy", "baseline"]).expect("baseline");
        assert_eq!(cli.args.policy.kind(), PolicyKind::Baseline);
    }
}
