//! `harvest calibrate laser`: runs the four calibration methods on a sample file (or on a
//! generated set), prints the Table-1-style comparison, and optionally writes method 4's
//! parameters to the calibration file.

use std::io::Write;
use std::path::PathBuf;

use harvest_hw::alacs::alacs_camera_intrinsics;

use crate::laser_samples::{GenerateError, SampleGeneratorConfig, generate_samples};
use harvest_laser::calibration::{
    CalibrationError, CalibrationFileError, CalibrationMethod, CalibrationOptions,
    CalibrationReport, ExtrinsicsRecord, FitRecord, LaserCalibrationFile, RansacOptions,
    SampleFileError, compare_methods, read_samples_csv, write_calibration_file,
};

/// Arguments of `harvest calibrate laser`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct CalibrateLaserArgs {
    /// CSV of samples `u_bar,v_bar,z_m` (normalised image coordinates, depth in metres).
    #[arg(required_unless_present = "generate", conflicts_with = "generate")]
    pub samples: Option<PathBuf>,
    /// Use a generated paper-like sample set (10 boards at 0.6-1.2 m, 3 points each, noise
    /// and 3 gross outliers) instead of a file.
    #[arg(long)]
    pub generate: bool,
    /// Seed of the generated samples and of the RANSAC draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RANSAC inlier threshold epsilon on |z - z_hat|, mm (the floor when
    /// --epsilon-scale-sigmas is positive).
    #[arg(long, default_value_t = 2.0)]
    pub epsilon_mm: f64,
    /// Each RANSAC method's threshold is max(epsilon, this many least-median-of-squares
    /// standard deviations of its own model); 0 uses epsilon alone. 2.5 is Rousseeuw's
    /// reweighting cut-off. It keeps the low-fidelity model (method 2), which cannot fit clean
    /// data to 2 mm, from voting out good samples with the outliers.
    #[arg(long, default_value_t = 2.5)]
    pub epsilon_scale_sigmas: f64,
    /// RANSAC hypotheses k_max.
    #[arg(long, default_value_t = 200)]
    pub iterations: usize,
    /// Write method 4's parameters to this TOML calibration file.
    #[arg(long, value_name = "PATH")]
    pub write: Option<PathBuf>,
    /// Print the report as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Why `harvest calibrate laser` failed; nothing was written.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateLaserError {
    #[error("--{name} {value} is invalid: {reason}")]
    InvalidArgument {
        name: &'static str,
        value: String,
        reason: &'static str,
    },
    #[error(transparent)]
    Samples(#[from] SampleFileError),
    #[error(transparent)]
    Generate(#[from] GenerateError),
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    #[error(transparent)]
    File(#[from] CalibrationFileError),
    #[error("could not print the report: {0}")]
    Output(#[source] std::io::Error),
}

/// Runs the command and prints the report to stdout.
pub fn run_calibrate_laser(
    args: &CalibrateLaserArgs,
) -> Result<CalibrationReport, CalibrateLaserError> {
    let stdout = std::io::stdout();
    run_calibrate_laser_to(args, &mut stdout.lock())
}

/// [`run_calibrate_laser`] printing to `out`.
pub fn run_calibrate_laser_to(
    args: &CalibrateLaserArgs,
    out: &mut impl Write,
) -> Result<CalibrationReport, CalibrateLaserError> {
    if !(args.epsilon_scale_sigmas.is_finite() && args.epsilon_scale_sigmas >= 0.0) {
        return Err(CalibrateLaserError::InvalidArgument {
            name: "epsilon-scale-sigmas",
            value: args.epsilon_scale_sigmas.to_string(),
            reason: "must be a non-negative number of standard deviations",
        });
    }
    if !(args.epsilon_mm.is_finite() && args.epsilon_mm > 0.0) {
        return Err(CalibrateLaserError::InvalidArgument {
            name: "epsilon-mm",
            value: args.epsilon_mm.to_string(),
            reason: "must be a positive number of millimetres",
        });
    }
    if args.iterations == 0 {
        return Err(CalibrateLaserError::InvalidArgument {
            name: "iterations",
            value: "0".into(),
            reason: "RANSAC needs at least one hypothesis",
        });
    }
    let (samples, clean) = match &args.samples {
        Some(path) => (read_samples_csv(path)?, None),
        None => {
            let generated = generate_samples(&SampleGeneratorConfig::paper_like(
                alacs_camera_intrinsics(),
                args.seed,
            ))?;
            let clean = generated.clean_mask();
            (generated.samples, Some(clean))
        }
    };
    let options = CalibrationOptions {
        ransac: RansacOptions {
            iterations: args.iterations,
            epsilon_m: args.epsilon_mm * 1e-3,
            scale_sigmas: args.epsilon_scale_sigmas,
            seed: args.seed,
        },
        ..CalibrationOptions::default()
    };
    let report = compare_methods(&samples, clean.as_deref(), &options)?;

    if let Some(path) = &args.write
        && let Some(chosen) = report.method(CalibrationMethod::HighFidelityRansac)
    {
        let file = LaserCalibrationFile {
            extrinsics: ExtrinsicsRecord {
                alpha_deg: chosen.alpha_deg,
                l0_mm: chosen.l0_mm,
                beta_deg: chosen.beta_deg.unwrap_or(0.0),
            },
            fit: FitRecord {
                method: chosen.method,
                samples: report.samples,
                used_samples: chosen.used_samples,
                epsilon_mm: args.epsilon_mm,
                mean_abs_error_mm: chosen.mean_abs_error_mm,
            },
        };
        write_calibration_file(path, &file)?;
        tracing::info!(path = %path.display(), "ALACS calibration written");
    }

    if args.json {
        serde_json::to_writer_pretty(&mut *out, &report)
            .map_err(|error| CalibrateLaserError::Output(error.into()))?;
        writeln!(out).map_err(CalibrateLaserError::Output)?;
    } else {
        write!(out, "{report}").map_err(CalibrateLaserError::Output)?;
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use harvest_laser::calibration::read_calibration_file;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: CalibrateLaserArgs,
    }

    fn parse(argv: &[&str]) -> Result<CalibrateLaserArgs, clap::Error> {
        Cli::try_parse_from(std::iter::once("laser").chain(argv.iter().copied()))
            .map(|cli| cli.args)
    }

    fn temp_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("harvest-laser-cli-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        dir
    }

    #[test]
    fn arguments_parse_and_conflict() {
        let args =
            parse(&["--generate", "--seed", "4", "--epsilon-mm", "1.5", "--json"]).expect("parse");
        assert!(args.generate && args.json && args.samples.is_none());
        assert_eq!((args.seed, args.epsilon_mm, args.iterations), (4, 1.5, 200));
        assert!(parse(&[]).is_err());
        assert!(parse(&["samples.csv", "--generate"]).is_err());
        assert_eq!(
            parse(&["s.csv"]).expect("parse").samples,
            Some(PathBuf::from("s.csv"))
        );
    }

    #[test]
    fn generate_prints_the_table_and_writes_method_4() {
        let dir = temp_dir("write");
        let path = dir.join("alacs.toml");
        let args = parse(&["--generate", "--write", path.to_str().expect("utf8")]).expect("parse");
        let mut out = Vec::new();
        let report = run_calibrate_laser_to(&args, &mut out).expect("run");
        let table = String::from_utf8(out).expect("utf8");
        assert!(table.contains("4 high-fidelity + RANSAC"), "{table}");
        let written = read_calibration_file(&path).expect("read back");
        let chosen = report
            .method(CalibrationMethod::HighFidelityRansac)
            .expect("row");
        assert_eq!(written.extrinsics.l0_mm, chosen.l0_mm);
        assert_eq!(written.fit.method, CalibrationMethod::HighFidelityRansac);

        let mut json = Vec::new();
        let args = parse(&["--generate", "--json"]).expect("parse");
        run_calibrate_laser_to(&args, &mut json).expect("run");
        let value: serde_json::Value = serde_json::from_slice(&json).expect("json");
        assert_eq!(value["methods"].as_array().map(Vec::len), Some(4));
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }

    #[test]
    fn bad_input_writes_nothing() {
        let dir = temp_dir("bad");
        let output = dir.join("alacs.toml");
        let write = output.to_str().expect("utf8");
        let samples = dir.join("samples.csv");
        std::fs::write(
            &samples,
            "u_bar,v_bar,z_m\n0.1,0.1,0.8\n0.2,0.1,0.9\n0.0,0.2,1.0\n",
        )
        .expect("write");
        let args = parse(&[samples.to_str().expect("utf8"), "--write", write]).expect("parse");
        let error = run_calibrate_laser_to(&args, &mut Vec::new()).expect_err("3 samples");
        assert!(matches!(
            error,
            CalibrateLaserError::Calibration(CalibrationError::TooFewSamples { got: 3, needed: 4 })
        ));
        std::fs::write(
            &samples,
            "0.1,0.1,0.8\n0.2,0.1,0.8\n0.0,0.2,0.8\n-0.1,0.0,0.8\n",
        )
        .expect("write");
        let error = run_calibrate_laser_to(&args, &mut Vec::new()).expect_err("one depth");
        assert!(error.to_string().contains("one depth"), "{error}");
        std::fs::write(&samples, "0.1,0.1,0.8\n0.2,nan,0.9\n").expect("write");
        let error = run_calibrate_laser_to(&args, &mut Vec::new()).expect_err("nan");
        assert!(
            error.to_string().contains("samples.csv:2: v_bar"),
            "{error}"
        );
        let args = parse(&["--generate", "--epsilon-mm", "0", "--write", write]).expect("parse");
        assert!(matches!(
            run_calibrate_laser_to(&args, &mut Vec::new()),
            Err(CalibrateLaserError::InvalidArgument {
                name: "epsilon-mm",
                ..
            })
        ));
        assert!(!output.exists());
        std::fs::remove_dir_all(&dir).expect("cleanup");
    }
}
