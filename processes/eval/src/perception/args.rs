//! Command line of `harvest eval perception`.

use std::path::PathBuf;

use harvest_perception::estimator::EstimatorKind;

/// A localization estimator of the perception pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum EstimatorArg {
    /// The paper's DBSCAN cluster-depth method.
    ClusterDepth,
    /// Robust sphere fit with an apple-radius prior (the improved method).
    SphereFit,
    /// Centroid of the mask points after Z-score outlier rejection.
    ZscoreCentroid,
}

impl EstimatorArg {
    pub fn kind(self) -> EstimatorKind {
        match self {
            Self::ClusterDepth => EstimatorKind::ClusterDepth,
            Self::SphereFit => EstimatorKind::SphereFit,
            Self::ZscoreCentroid => EstimatorKind::ZScoreCentroid,
        }
    }
}

/// Arguments of `harvest eval perception`.
#[derive(Debug, Clone, clap::Args)]
pub struct EvalPerceptionArgs {
    /// Scenario presets (`default`, `ideal`, `gala_vertical_wall`, `fuji_ufo`) or scenario TOML
    /// files, comma-separated; each is evaluated and reported separately.
    #[arg(long, value_delimiter = ',', default_value = "default")]
    pub scenario: Vec<String>,
    /// Frames per scenario; frame i shows the world generated from seed + i.
    #[arg(long, default_value_t = 30)]
    pub frames: u32,
    /// Frames of the scenario with its apples removed (seed + i), for false detections;
    /// default: as many as --frames.
    #[arg(long)]
    pub empty_frames: Option<u32>,
    /// First world seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write the report as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Estimators to evaluate on the same frames, comma-separated.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "cluster-depth,sphere-fit,zscore-centroid"
    )]
    pub estimators: Vec<EstimatorArg>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        args: EvalPerceptionArgs,
    }

    #[test]
    fn defaults_and_lists_parse() {
        let cli = Cli::try_parse_from(["eval"]).expect("defaults");
        assert_eq!(cli.args.scenario, vec!["default".to_owned()]);
        assert_eq!(cli.args.frames, 30);
        assert_eq!(cli.args.empty_frames, None);
        assert_eq!(
            cli.args.estimators,
            vec![
                EstimatorArg::ClusterDepth,
                EstimatorArg::SphereFit,
                EstimatorArg::ZscoreCentroid
            ]
        );
        let cli = Cli::try_parse_from([
            "eval",
            "--scenario",
            "ideal,fuji_ufo",
            "--estimators",
            "sphere-fit",
            "--frames",
            "3",
            "--json",
            "/tmp/x.json",
        ])
        .expect("explicit");
        assert_eq!(cli.args.scenario, vec!["ideal", "fuji_ufo"]);
        assert_eq!(cli.args.estimators, vec![EstimatorArg::SphereFit]);
        assert_eq!(cli.args.frames, 3);
        assert!(Cli::try_parse_from(["eval", "--estimators", "magic"]).is_err());
    }
}
