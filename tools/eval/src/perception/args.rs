//! Command line of `harvest eval perception`.

use std::path::PathBuf;

use harvest_perception::depth_source::DepthSource;
use harvest_perception::detector::DetectorKind;
use harvest_perception::estimator::EstimatorKind;

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
        value_delimiter = ',',
        default_value = "cluster-depth,sphere-fit,zscore-centroid"
    )]
    pub estimators: Vec<EstimatorKind>,
    /// Depth images to localize from, comma-separated: `tof` (the ToF camera's) and/or
    /// `lidar-fused` (a window of the simulated Mid-70 fused into the frame's geometry); every
    /// estimator runs on each.
    #[arg(long, value_delimiter = ',', default_value = "tof,lidar-fused")]
    pub depth_sources: Vec<DepthSource>,
    /// LiDAR integration per frame for `lidar-fused`, seconds (the LiDAR launch profile's).
    #[arg(long, default_value_t = 1.0)]
    pub lidar_integration_s: f64,
    /// Detector: `color-segmentation` (default) or `onnx` (with `--model`), the same choice as
    /// `harvest perception --detector`.
    #[arg(long)]
    pub detector: Option<DetectorKind>,
    /// The ONNX model of the `onnx` detector (YOLOv8/YOLO11 detect or segment export; CPU
    /// provider, default thresholds; see domain/perception/src/detector/onnx/config.rs).
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Repeated localizations per distance of the Table-III comparison (LiDAR-fused versus ToF
    /// at 0.5, 1.2 and 1.8 m), printed when `lidar-fused` is a depth source; 0 leaves it out.
    #[arg(long, default_value_t = 20)]
    pub table_iii_trials: usize,
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
                EstimatorKind::ClusterDepth,
                EstimatorKind::SphereFit,
                EstimatorKind::ZScoreCentroid
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
        assert_eq!(cli.args.estimators, vec![EstimatorKind::SphereFit]);
        assert_eq!(cli.args.frames, 3);
        assert!(Cli::try_parse_from(["eval", "--estimators", "magic"]).is_err());
    }
}
