//! Command line of `harvest eval row`.

use std::path::PathBuf;

use crate::harvest::{PolicyArg, TimingArg};

/// Where the detection sets come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DetectionsArg {
    /// Perception's own node (`harvest_perception::node::PerceptionNode`) on frames the
    /// simulator's ToF camera renders (the perception-in-the-loop run).
    Perception,
    /// The ground truth through the camera's depth-noise model (`harvest eval harvest`'s
    /// model: no perception failures; fast).
    Model,
}

/// Arguments of `harvest eval row`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalRowArgs {
    /// Row scenarios: `two_stops`, `three_sections` (the files in `sim/rows/`) or row TOML
    /// files. Each is run with every seed and arm count.
    #[arg(long, num_args = 1.., default_values_t = ["two_stops".to_owned(), "three_sections".to_owned()])]
    pub rows: Vec<String>,
    /// World seed of the first run of each row; run k uses seed + k.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seeds per row.
    #[arg(long, default_value_t = 2)]
    pub seeds: u32,
    /// Arm counts to compare: 1 (arm 1 alone), 2 (both).
    #[arg(long, num_args = 1.., default_values_t = [1u8, 2u8], value_parser = clap::value_parser!(u8).range(1..=2))]
    pub arms: Vec<u8>,
    /// Vacuum coordination policy.
    #[arg(long, value_enum, default_value = "2024")]
    pub policy: PolicyArg,
    /// Hardware timing of the simulated robot.
    #[arg(long, value_enum, default_value = "scenario")]
    pub timing: TimingArg,
    /// Where the detection sets come from.
    #[arg(long, value_enum, default_value = "perception")]
    pub detections: DetectionsArg,
    /// While the arms harvest, a frame is rendered at least this often (and after every
    /// attempt), simulated s. Perception's latency is simulated as `--perception-latency-s`.
    #[arg(long, default_value_t = 1.5)]
    pub frame_interval_s: f64,
    /// Simulated time from a frame's capture to its detections reaching the stack, s.
    #[arg(long, default_value_t = 0.1)]
    pub perception_latency_s: f64,
    /// A stop is harvested once nothing happened for this long (or the vacuum supervisor has
    /// nothing left), ms (the executive's `--stop-quiet-ms`).
    #[arg(long, default_value_t = 4000)]
    pub stop_quiet_ms: u64,
    /// Simulated time limit per row, s.
    #[arg(long, default_value_t = 1800.0)]
    pub max_row_s: f64,
    /// Also write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Print every failed attempt with the ground truth behind it (origin, picking-point
    /// error, stem against the cup's force, nearest apple and its state).
    #[arg(long)]
    pub failures: bool,
}

impl Default for EvalRowArgs {
    fn default() -> Self {
        Self {
            rows: vec!["two_stops".to_owned(), "three_sections".to_owned()],
            seed: 1,
            seeds: 2,
            arms: vec![1, 2],
            policy: PolicyArg::V2024,
            timing: TimingArg::Scenario,
            detections: DetectionsArg::Perception,
            frame_interval_s: 1.5,
            perception_latency_s: 0.1,
            stop_quiet_ms: 4000,
            max_row_s: 1800.0,
            json: None,
            failures: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: EvalRowArgs,
    }

    #[test]
    fn defaults_match_and_values_parse() {
        let cli = Cli::try_parse_from(["x"]).expect("defaults");
        let defaults = EvalRowArgs::default();
        assert_eq!(cli.args.rows, defaults.rows);
        assert_eq!(cli.args.arms, defaults.arms);
        assert_eq!(cli.args.seeds, defaults.seeds);
        assert_eq!(cli.args.detections, DetectionsArg::Perception);
        let cli = Cli::try_parse_from([
            "x",
            "--rows",
            "a.toml",
            "--arms",
            "2",
            "--detections",
            "model",
        ])
        .expect("values");
        assert_eq!(cli.args.rows, ["a.toml"]);
        assert_eq!(cli.args.arms, [2]);
        assert_eq!(cli.args.detections, DetectionsArg::Model);
        assert!(Cli::try_parse_from(["x", "--arms", "3"]).is_err());
    }
}
