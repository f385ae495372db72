//! `harvest laser`: `laser/scan_request` -> ALACS interval scan -> `laser/scan_result`.
//!
//! [`LaserTask`] (`harvest_laser::task`: the requests answered in arrival order by the scan
//! service, one device exchange per tick) on the node runtime with the ALACS unit's driver as
//! its devices ([`UnitDevices`] over [`SimAlacsUnit`], `hw/alacs/*`), woken by each request on
//! `laser/scan_request` ([`Wake::Input`]) and ticked back to back while a scan runs, with the
//! heartbeat between ticks: a scan is 12 exchanges (laser on, 5 x move + capture, laser off),
//! each bounded by `--device-timeout-ms`. The tick is the runtime's: `safety/emergency_stop`
//! first (engaged: the laser off before anything else, the scan under way ended and answered
//! with status `DeviceError`, never resumed), then the unit's answer to the previous exchange,
//! the requests, the step and the next exchange. However the run ends, the laser is switched
//! off and every request read is answered. This file wires the arguments into it.
//!
//! Frames: requests carry the rough centre in the ToF colour-camera frame; results come back in
//! the same frame (see [`harvest_laser::service`]).

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use harvest_hw::alacs::{
    ALACS_FROM_TOF_CAMERA, AlacsError, AlacsExtrinsics, SimAlacsUnit, alacs_camera_intrinsics,
};
use harvest_ipc::catalogue::LASER_SCAN_REQUEST;
use harvest_ipc::{Context, Domain};
use harvest_laser::calibration::{CalibrationFileError, read_extrinsics};
use harvest_laser::extraction::ExtractionError;
use harvest_laser::service::ScanService;
use harvest_laser::task::LaserTask;
use harvest_laser::unit_devices::UnitDevices;
use harvest_node::RunnerConfig;
use harvest_robot_model::ModeSource;
use harvest_runtime::{RunError, Wake, WakeOptions, run_on_wake};

/// Arguments of `harvest laser`.
#[derive(Debug, Clone, PartialEq, clap::Args)]
pub struct LaserArgs {
    /// ALACS calibration file (TOML, as written by `harvest calibrate laser --write`), required:
    /// the unit's laser-camera extrinsics. The simulated unit's is `sim/alacs_calibration.toml`.
    #[arg(long, value_name = "PATH")]
    pub calibration: Option<PathBuf>,
    /// Longest wait for one answer of the ALACS device (the simulator renders an image per
    /// capture), ms. Keep it under the supervisor's 3 s hang timeout.
    #[arg(long, default_value_t = 2000)]
    pub device_timeout_ms: u64,
}

/// Why the laser process stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum LaserProcessError {
    /// No calibration file was given: no production default stands in for it.
    #[error("--calibration FILE is required: the ALACS unit's laser-camera extrinsics")]
    MissingCalibration,
    /// The calibration file could not be read or holds unusable extrinsics.
    #[error(transparent)]
    Calibration(#[from] CalibrationFileError),
    /// `--device-timeout-ms` is outside what the supervisor tolerates.
    #[error(
        "--device-timeout-ms {value} is invalid: use 1-2900 ms (the supervisor's hang timeout is 3 s)"
    )]
    InvalidTimeout { value: u64 },
    /// The scan pipeline could not be configured.
    #[error("scan pipeline: {0}")]
    Setup(#[from] ExtractionError),
    /// The ALACS driver could not open its hardware channels.
    #[error("ALACS driver: {0}")]
    Driver(#[from] AlacsError),
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    /// The run ended on an error (transport, wait set).
    #[error(transparent)]
    Run(#[from] RunError),
}

harvest_ipc::from_ipc_errors!(LaserProcessError);

/// The extrinsics the process triangulates with: the calibration file's.
pub fn load_extrinsics(args: &LaserArgs) -> Result<AlacsExtrinsics, LaserProcessError> {
    let Some(path) = &args.calibration else {
        return Err(LaserProcessError::MissingCalibration);
    };
    Ok(read_extrinsics(path)?)
}

/// Runs until SIGINT/SIGTERM.
pub fn run(args: &LaserArgs, domain: &Domain, process_name: &str) -> Result<(), LaserProcessError> {
    run_until(args, domain, process_name, &AtomicBool::new(false))
}

/// [`run`] that also stops once `stop` is set (checked at each heartbeat, and between the
/// exchanges of a scan): tests run the process on a thread.
pub fn run_until(
    args: &LaserArgs,
    domain: &Domain,
    process_name: &str,
    stop: &AtomicBool,
) -> Result<(), LaserProcessError> {
    if !(1..=2900).contains(&args.device_timeout_ms) {
        return Err(LaserProcessError::InvalidTimeout {
            value: args.device_timeout_ms,
        });
    }
    let extrinsics = load_extrinsics(args)?;
    let intrinsics = alacs_camera_intrinsics();
    let service = ScanService::new(extrinsics, intrinsics, ALACS_FROM_TOF_CAMERA)?;

    let context = Context::new(domain, process_name)?;
    let unit = SimAlacsUnit::connect(
        &context,
        intrinsics,
        Duration::from_millis(args.device_timeout_ms),
    )?;
    tracing::info!(
        alpha_deg = extrinsics.alpha_rad.to_degrees(),
        l0_mm = extrinsics.l0_m * 1e3,
        beta_deg = extrinsics.beta_rad.to_degrees(),
        calibration = ?args.calibration,
        "laser scanner running"
    );
    let options = WakeOptions {
        wake: Wake::Input {
            topic: LASER_SCAN_REQUEST.spec.topic,
        },
        runner: RunnerConfig {
            // A read takes the last exchange's answer and never fails.
            max_read_failures: u32::MAX,
            // The mode does not restrict scanning (harvest_laser::task).
            mode_source: ModeSource::WithoutOperator,
        },
        // The laser is an emitter on a moving slide: it obeys the stop.
        obeys: true,
        stop: Some(stop),
    };
    let finished = run_on_wake(
        &context,
        LaserTask::<SimAlacsUnit>::new(service),
        UnitDevices::new(unit),
        options,
    )?;
    let counts = finished.runner.node().counts();
    let (read_failures, exchange_failures) = finished.runner.device_failures();
    tracing::info!(
        answered = counts.answered,
        refined = counts.refined,
        device_errors = counts.device_errors,
        stopped = counts.stopped,
        exchange_failures,
        read_failures,
        "laser scanner stopped"
    );
    finished.result?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(calibration: Option<PathBuf>) -> LaserArgs {
        LaserArgs {
            calibration,
            device_timeout_ms: 2000,
        }
    }

    /// The simulated robot's calibration file holds the extrinsics the simulator renders with.
    #[test]
    fn sim_calibration_file_holds_the_simulated_units_extrinsics() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../sim/alacs_calibration.toml"
        );
        let loaded = load_extrinsics(&args(Some(path.into()))).expect("sim calibration");
        let truth = AlacsExtrinsics::paper_table1();
        assert!((loaded.alpha_rad - truth.alpha_rad).abs() < 1e-12);
        assert!((loaded.l0_m - truth.l0_m).abs() < 1e-12);
        assert!((loaded.beta_rad - truth.beta_rad).abs() < 1e-12);
    }

    #[test]
    fn a_missing_calibration_names_the_flag() {
        let error = load_extrinsics(&args(None)).expect_err("no default");
        assert!(error.to_string().contains("--calibration"), "{error}");
    }
}
