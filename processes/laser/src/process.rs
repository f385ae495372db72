//! `harvest laser`: `laser/scan_request` -> ALACS interval scan -> `laser/scan_result`.
//!
//! Event-driven: the wait set wakes on scan requests (and on the heartbeat interval). Each
//! request is answered in arrival order by [`ScanService::answer`] driving the ALACS unit's
//! driver ([`SimAlacsUnit`] over `hw/alacs/*`); one scan is 12 device exchanges (laser on,
//! 5 x move + capture, laser off), so the heartbeat is also sent between exchanges while a scan
//! runs, or the supervisor would take the busy process for a hung one.
//!
//! Frames: requests carry the rough centre in the ToF colour-camera frame; results come back in
//! the same frame (see [`harvest_laser::service`]).

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use harvest_hw::alacs::{
    ALACS_FROM_TOF_CAMERA, AlacsError, AlacsExtrinsics, SimAlacsUnit, alacs_camera_intrinsics,
};
use harvest_ipc::catalogue::{LASER_SCAN_REQUEST, LASER_SCAN_RESULT};
use harvest_ipc::payloads::{LaserScanResult, LaserScanStatus, ProcessRunState};
use harvest_ipc::{Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, Waiter, WireCode};

use harvest_hw::DeviceError;
use harvest_laser::calibration::{CalibrationFileError, read_extrinsics};
use harvest_laser::extraction::ExtractionError;
use harvest_laser::scan::ScanError;
use harvest_laser::service::{ScanRequestError, ScanService};

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

/// [`run`] that also stops once `stop` is set (checked at each heartbeat, so within
/// [`HEARTBEAT_PERIOD`] of setting it when no scan is running): tests run the process on a thread.
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
    let mut service = ScanService::new(extrinsics, intrinsics, ALACS_FROM_TOF_CAMERA)?;

    let context = Context::new(domain, process_name)?;
    let requests = context.subscriber(LASER_SCAN_REQUEST)?;
    let mut results = context.publisher(LASER_SCAN_RESULT)?;
    let mut unit = SimAlacsUnit::connect(
        &context,
        intrinsics,
        Duration::from_millis(args.device_timeout_ms),
    )?;
    let mut health = HealthReporter::new(&context)?;
    let waiter = Waiter::new()?;
    let request_guard = waiter.attach_listener(requests.listener())?;
    let heartbeat = waiter.attach_interval(HEARTBEAT_PERIOD)?;

    let mut scans = ScanCounters::default();
    let mut last_beat = Instant::now();
    tracing::info!(
        alpha_deg = extrinsics.alpha_rad.to_degrees(),
        l0_mm = extrinsics.l0_m * 1e3,
        beta_deg = extrinsics.beta_rad.to_degrees(),
        calibration = ?args.calibration,
        "laser scanner running"
    );
    waiter
        .run(|attachment| -> Result<Flow, LaserProcessError> {
            if attachment.has_event_from(&request_guard) {
                while let Some(sample) = requests.receive()? {
                    let request = *sample;
                    drop(sample);
                    let mut result = LaserScanResult::default();
                    let mut beat_during_scan = || {
                        if last_beat.elapsed() >= HEARTBEAT_PERIOD {
                            last_beat = Instant::now();
                            if let Err(error) = health.report(
                                scans.run_state(),
                                scans.answered,
                                "scanning_apple",
                                u64::from(request.apple_id),
                            ) {
                                tracing::debug!(%error, "heartbeat during a scan failed");
                            }
                        }
                    };
                    let outcome =
                        service.answer(&mut unit, &request, &mut result, &mut beat_during_scan);
                    results.publish(&result)?;
                    scans.count(&result);
                    match outcome {
                        Ok(scan) => tracing::debug!(
                            request_seq = request.request_seq,
                            apple_id = request.apple_id,
                            selected = scan.selected,
                            position_in_camera_m = ?result.position_in_camera_m,
                            scan_ms = result.scan_duration_ns / 1_000_000,
                            "apple scanned"
                        ),
                        Err(error) if result.status == LaserScanStatus::DeviceError => {
                            if let ScanRequestError::Scan(ScanError::Device(device)) = &error {
                                health.note_device_error(device.kind().into());
                            }
                            tracing::warn!(
                                request_seq = request.request_seq,
                                apple_id = request.apple_id,
                                %error,
                                "scan failed"
                            )
                        }
                        Err(error) => tracing::debug!(
                            request_seq = request.request_seq,
                            apple_id = request.apple_id,
                            status = ?result.status,
                            %error,
                            "scan gave no position"
                        ),
                    }
                }
            }
            if attachment.has_event_from(&heartbeat) {
                last_beat = Instant::now();
                health.report(
                    scans.run_state(),
                    scans.answered,
                    "last_scan_ms",
                    scans.last_scan_ns / 1_000_000,
                )?;
                if stop.load(Ordering::Relaxed) {
                    return Ok(Flow::Stop);
                }
            }
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    tracing::info!(
        answered = scans.answered,
        refined = scans.refined,
        device_errors = scans.device_errors,
        dropped_requests = requests.dropped_count(),
        "laser scanner stopped"
    );
    Ok(())
}

/// What the process has answered so far (heartbeat figures).
#[derive(Debug, Clone, Copy, Default)]
struct ScanCounters {
    answered: u64,
    refined: u64,
    device_errors: u64,
    last_status: WireCode<LaserScanStatus>,
    last_scan_ns: u64,
}

impl ScanCounters {
    fn count(&mut self, result: &LaserScanResult) {
        self.answered += 1;
        self.refined += u64::from(result.status == LaserScanStatus::Ok);
        self.device_errors += u64::from(result.status == LaserScanStatus::DeviceError);
        self.last_status = result.status;
        self.last_scan_ns = result.scan_duration_ns;
    }

    /// Degraded while the last scan failed on the device.
    fn run_state(&self) -> ProcessRunState {
        if self.last_status == LaserScanStatus::DeviceError {
            ProcessRunState::Degraded
        } else {
            ProcessRunState::Running
        }
    }
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
