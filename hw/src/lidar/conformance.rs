//! Behaviour every [`Lidar`] implementation must show, written once and generic over the trait
//! (harness: [`crate::conformance`]):
//!
//! - each capture delivers one integration window: scan time held not above the window (one
//!   firing of slack) and not under half of it, at least a minimum of returns, at most a cloud;
//! - every return is finite, inside the field of view's cone and the working range, both
//!   widened by the spec's noise;
//! - capture stamps are on the stack's clock (`CLOCK_MONOTONIC`, close to now), strictly
//!   increase, and advance by about one window;
//! - a LiDAR whose device delivers nothing returns `Ok(false)` at its timeout.
//!
//! Clouds are 1.6 MB: the suite allocates one on the heap and reuses it.

use super::{Lidar, LidarSpec};
use crate::conformance::{Check, ConformanceError, ConformanceReport, call, run_checks, violated};
use harvest_ipc::MonotonicClock;
use harvest_ipc::payload::boxed_zeroed;
use harvest_ipc::payloads::PointCloud;
use harvest_ipc::payloads::point_cloud::POINT_CLOUD_CAPACITY;
use std::time::Duration;

/// What the installation declares about its LiDAR, and the suite's bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LidarConformanceConfig {
    /// The device's scan and error model.
    pub spec: LidarSpec,
    /// The integration window the drivers under test were opened with.
    pub integration: Duration,
    /// Windows captured by each check.
    pub windows: usize,
    /// Fewest returns a window of the test scene must hold.
    pub min_points_per_window: usize,
    /// Standard deviations of the spec's noise the range and cone are widened by.
    pub noise_sigmas: f64,
    /// Capture timeout for a live device (a liveness bound far above the window).
    pub capture_timeout: Duration,
    /// Capture timeout used on the silent device.
    pub silent_timeout: Duration,
}

impl LidarConformanceConfig {
    /// The Mid-70 with the given window, three windows per check, a tenth of the nominal returns
    /// at least.
    pub fn mid70(integration: Duration) -> Self {
        let spec = LidarSpec::mid70();
        Self {
            spec,
            integration,
            windows: 3,
            min_points_per_window: (spec.point_rate_hz * integration.as_secs_f64() / 10.0) as usize,
            noise_sigmas: 5.0,
            capture_timeout: integration * 4 + Duration::from_secs(10),
            silent_timeout: Duration::from_millis(200),
        }
    }
}

/// Runs the live checks on fresh drivers from `make`, then the timeout check on a driver from
/// `make_silent` whose device is not there.
pub fn conformance_suite<L: Lidar, S: Lidar>(
    config: &LidarConformanceConfig,
    make: impl FnMut() -> L,
    mut make_silent: impl FnMut() -> S,
) -> Result<ConformanceReport, ConformanceError> {
    let checks: [Check<LidarConformanceConfig, L>; 3] = [
        (
            "windows_hold_the_integration_time",
            windows_hold_the_integration_time,
        ),
        (
            "returns_lie_in_the_cone_and_range",
            returns_lie_in_the_cone_and_range,
        ),
        (
            "stamps_are_monotonic_and_advance_by_a_window",
            stamps_advance_by_a_window,
        ),
    ];
    let mut report = run_checks("lidar", config, &checks, make, |_, _| Ok(()))?;
    silent_device_times_out(config, &mut make_silent())?;
    report.checks_passed.push("silent_device_times_out");
    Ok(report)
}

/// Captures `config.windows` windows, handing each to `inspect`.
fn capture_windows<L: Lidar>(
    check: &'static str,
    config: &LidarConformanceConfig,
    lidar: &mut L,
    mut inspect: impl FnMut(usize, &PointCloud) -> Result<(), ConformanceError>,
) -> Result<(), ConformanceError> {
    let mut cloud: Box<PointCloud> = boxed_zeroed();
    for index in 0..config.windows {
        // A driver may report a transient error (e.g. while its device connects): one retry.
        let delivered = match lidar.capture_into(&mut cloud, config.capture_timeout) {
            Ok(delivered) => delivered,
            Err(_) => call(check, || "capture_into (retry)".to_string(), {
                lidar.capture_into(&mut cloud, config.capture_timeout)
            })?,
        };
        if !delivered {
            return Err(violated(
                check,
                format!(
                    "window {index}: nothing delivered within {:?}",
                    config.capture_timeout
                ),
            ));
        }
        inspect(index, &cloud)?;
    }
    Ok(())
}

fn windows_hold_the_integration_time<L: Lidar>(
    config: &LidarConformanceConfig,
    lidar: &mut L,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "windows_hold_the_integration_time";
    let window_ns = config.integration.as_nanos() as u64;
    let firing_ns = (1e9 / config.spec.point_rate_hz) as u64;
    capture_windows(CHECK, config, lidar, |index, cloud| {
        let held = cloud.meta.integration_ns;
        if held > window_ns + firing_ns || held < window_ns / 2 {
            return Err(violated(
                CHECK,
                format!("window {index} holds {held} ns of scan for a {window_ns} ns window"),
            ));
        }
        let count = cloud.meta.point_count as usize;
        if count < config.min_points_per_window || count > POINT_CLOUD_CAPACITY {
            return Err(violated(
                CHECK,
                format!(
                    "window {index} holds {count} returns, expected {}..={POINT_CLOUD_CAPACITY}",
                    config.min_points_per_window
                ),
            ));
        }
        Ok(())
    })
}

fn returns_lie_in_the_cone_and_range<L: Lidar>(
    config: &LidarConformanceConfig,
    lidar: &mut L,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "returns_lie_in_the_cone_and_range";
    let spec = config.spec;
    let range_slack_m = config.noise_sigmas * spec.range_sigma_m + 0.002;
    let [near_m, far_m] = [
        spec.range_m[0] - range_slack_m,
        spec.range_m[1] + range_slack_m,
    ];
    let max_angle_rad = spec.half_fov_rad()
        + (config.noise_sigmas * spec.angular_sigma_deg).to_radians()
        + 0.2_f64.to_radians();
    capture_windows(CHECK, config, lidar, |index, cloud| {
        for (k, point) in cloud.valid_points().iter().enumerate() {
            let p = point.position_m().map(f64::from);
            let range_m = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let angle_rad = (p[0] / range_m).clamp(-1.0, 1.0).acos();
            let good = point.is_finite()
                && point.intensity.is_finite()
                && (near_m..=far_m).contains(&range_m)
                && angle_rad <= max_angle_rad;
            if !good {
                return Err(violated(
                    CHECK,
                    format!(
                        "window {index} return {k} at {p:?} m: range {range_m:.3} m (valid \
                         {near_m:.3}..{far_m:.3}), {:.2} deg off the boresight (at most {:.2})",
                        angle_rad.to_degrees(),
                        max_angle_rad.to_degrees()
                    ),
                ));
            }
        }
        Ok(())
    })
}

fn stamps_advance_by_a_window<L: Lidar>(
    config: &LidarConformanceConfig,
    lidar: &mut L,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "stamps_are_monotonic_and_advance_by_a_window";
    let window_ns = config.integration.as_nanos() as u64;
    let mut previous: Option<u64> = None;
    capture_windows(CHECK, config, lidar, |index, cloud| {
        let stamp = cloud.header.capture_ns;
        let now = MonotonicClock::read_ns();
        if stamp > now || now - stamp > 2_000_000_000 + window_ns {
            return Err(violated(
                CHECK,
                format!("window {index} stamped {stamp} ns, the stack clock reads {now} ns"),
            ));
        }
        if let Some(before) = previous {
            let step = stamp.saturating_sub(before);
            if stamp <= before || step < window_ns / 2 || step > window_ns * 3 {
                return Err(violated(
                    CHECK,
                    format!(
                        "window {index} stamped {stamp} ns after {before} ns: step {step} ns for \
                         a {window_ns} ns window"
                    ),
                ));
            }
        }
        previous = Some(stamp);
        Ok(())
    })
}

fn silent_device_times_out<S: Lidar>(
    config: &LidarConformanceConfig,
    lidar: &mut S,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "silent_device_times_out";
    let mut cloud: Box<PointCloud> = boxed_zeroed();
    let delivered = call(CHECK, || "capture_into on a silent device".to_string(), {
        lidar.capture_into(&mut cloud, config.silent_timeout)
    })?;
    if delivered {
        return Err(violated(
            CHECK,
            "a silent device delivered a window".to_string(),
        ));
    }
    Ok(())
}
