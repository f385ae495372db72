//! Behaviour every [`RgbdCamera`] implementation must show, written once and generic over the
//! trait (harness: [`crate::conformance`]):
//!
//! - frames carry the declared geometry: colour and depth intrinsics as the installation
//!   declares them (the TL460's 1920x1080 / 640x480 by default), consistent with the buffers,
//!   and a registration that is a rigid transform between sensors a few centimetres apart;
//! - depth pixels are 0 (no return) or within the working range widened by the spec's noise;
//!   a colour-only camera (a GigE Vision camera: [`CameraConformanceConfig::color_only`]) says
//!   so in every frame (`RgbdFrameMeta::FLAG_COLOR_ONLY`) and leaves every depth pixel 0, and a
//!   ToF camera never sets that flag;
//! - the colour image has content (not one value everywhere);
//! - capture stamps strictly increase from frame to frame;
//! - a camera that delivers nothing returns `Ok(false)` at its timeout and leaves the caller's
//!   buffer untouched.
//!
//! Frames are multi-megabyte: the suite allocates one on the heap and reuses it.

use super::RgbdCamera;
use crate::conformance::{Check, ConformanceError, ConformanceReport, call, run_checks, violated};
use harvest_ipc::camera_model::{CameraIntrinsics, RigidTransform};
use harvest_ipc::payload::boxed_zeroed;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use std::time::Duration;

/// Working range of the TL460's depth, mm (0.3-9.5 m, [dual-arm sec. 2.1]).
pub const TL460_RANGE_MM: [f64; 2] = [300.0, 9500.0];
/// TL460 depth accuracy: +/-(4 mm + 0.25 % of depth), taken as one standard deviation.
pub const TL460_ACCURACY_MM: f64 = 4.0;
/// Depth-proportional part of the TL460 depth accuracy.
pub const TL460_ACCURACY_FRACTION: f64 = 0.0025;

/// What the installation declares about its camera, and the suite's bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraConformanceConfig {
    /// Declared colour intrinsics (frames must carry exactly these).
    pub rgb_intrinsics: CameraIntrinsics,
    /// Declared depth intrinsics.
    pub depth_intrinsics: CameraIntrinsics,
    /// Largest distance between the two sensors' optical centres, m.
    pub max_baseline_m: f64,
    /// Valid depth readings, mm: the working range widened by `noise_sigmas` standard
    /// deviations of the accuracy spec at each end.
    pub valid_depth_mm: [f64; 2],
    /// Frames captured by the stamp and depth checks.
    pub frames: usize,
    /// Capture timeout for a live camera (a liveness bound far above the frame period).
    pub capture_timeout: Duration,
    /// Capture timeout used on the silent camera.
    pub silent_timeout: Duration,
    /// The camera has no depth sensor: frames are flagged colour only and carry no depth.
    pub color_only: bool,
}

impl CameraConformanceConfig {
    /// The TL460 as simulated ([`CameraIntrinsics::tl460_rgb`], [`CameraIntrinsics::tl460_depth`]),
    /// depth valid within 4 sigma of the working range.
    pub fn tl460() -> Self {
        let noise_sigmas = 4.0;
        let sigma_mm = |depth_mm: f64| TL460_ACCURACY_MM + TL460_ACCURACY_FRACTION * depth_mm;
        let [near_mm, far_mm] = TL460_RANGE_MM;
        Self {
            rgb_intrinsics: CameraIntrinsics::tl460_rgb(),
            depth_intrinsics: CameraIntrinsics::tl460_depth(),
            max_baseline_m: 0.10,
            valid_depth_mm: [
                near_mm - noise_sigmas * sigma_mm(near_mm),
                far_mm + noise_sigmas * sigma_mm(far_mm),
            ],
            frames: 4,
            capture_timeout: Duration::from_secs(10),
            silent_timeout: Duration::from_millis(100),
            color_only: false,
        }
    }

    /// A colour-only camera with the declared colour intrinsics: its depth grid is the one
    /// perception lays the LiDAR's depth on ([`crate::rgbd_camera::gige::fused_depth_grid`]),
    /// registered by the identity.
    pub fn color_only(rgb_intrinsics: CameraIntrinsics) -> Self {
        Self {
            rgb_intrinsics,
            depth_intrinsics: crate::rgbd_camera::gige::fused_depth_grid(&rgb_intrinsics),
            max_baseline_m: 0.0,
            color_only: true,
            ..Self::tl460()
        }
    }
}

/// Runs the live checks on fresh cameras from `make`, then the timeout check on a camera from
/// `make_silent` that has no frames to deliver (e.g. a driver whose device is not running).
pub fn conformance_suite<C: RgbdCamera, S: RgbdCamera>(
    config: &CameraConformanceConfig,
    make: impl FnMut() -> C,
    mut make_silent: impl FnMut() -> S,
) -> Result<ConformanceReport, ConformanceError> {
    let checks: [Check<CameraConformanceConfig, C>; 2] = [
        ("geometry_as_declared", check_geometry),
        ("stamps_increase_and_depth_valid", check_stream),
    ];
    let mut report = run_checks("rgbd camera", config, &checks, make, |_, _| Ok(()))?;
    check_timeout(config, &mut make_silent())?;
    report.checks_passed.push("timeout_without_frame");
    Ok(report)
}

/// Captures one frame into `frame`; a timeout is a failure of `check`.
fn capture<C: RgbdCamera>(
    check: &'static str,
    config: &CameraConformanceConfig,
    camera: &mut C,
    frame: &mut RgbdFrame,
) -> Result<(), ConformanceError> {
    let timeout = config.capture_timeout;
    let captured = call(
        check,
        || format!("capture_into(frame, {} ms)", timeout.as_millis()),
        camera.capture_into(frame, timeout),
    )?;
    if captured {
        Ok(())
    } else {
        Err(violated(
            check,
            format!(
                "no frame within {} ms from a live camera",
                timeout.as_millis()
            ),
        ))
    }
}

fn intrinsics_sane(
    which: &str,
    intrinsics: &CameraIntrinsics,
    width: usize,
    height: usize,
) -> Result<(), String> {
    let size = (intrinsics.width_px as usize, intrinsics.height_px as usize);
    if size != (width, height) {
        return Err(format!(
            "{which} intrinsics are {size:?} px, the buffer is {width}x{height}"
        ));
    }
    if let Some(problem) = intrinsics.problem() {
        return Err(format!("{which} {problem}"));
    }
    let inside = (0.0..width as f64).contains(&intrinsics.cx_px)
        && (0.0..height as f64).contains(&intrinsics.cy_px);
    if !inside {
        return Err(format!(
            "{which} principal point ({}, {}) px lies outside the {width}x{height} image",
            intrinsics.cx_px, intrinsics.cy_px
        ));
    }
    Ok(())
}

/// Rotation orthonormal with determinant +1 (to 1e-6), translation under `max_baseline_m`.
fn registration_rigid(transform: &RigidTransform, max_baseline_m: f64) -> Result<(), String> {
    if !transform.is_rigid() {
        return Err(format!(
            "color_from_depth is not a rigid transform (orthonormal rotation, determinant +1): \
             {transform:?}"
        ));
    }
    let baseline_m = transform
        .translation_m
        .iter()
        .map(|t| t * t)
        .sum::<f64>()
        .sqrt();
    if baseline_m.is_nan() || baseline_m > max_baseline_m {
        return Err(format!(
            "color_from_depth baseline {baseline_m} m exceeds {max_baseline_m} m"
        ));
    }
    Ok(())
}

/// The frame's intrinsics are the declared ones and match the buffers; the registration is
/// rigid with a short baseline.
fn check_geometry<C: RgbdCamera>(
    config: &CameraConformanceConfig,
    camera: &mut C,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "geometry_as_declared";
    let mut frame = boxed_zeroed::<RgbdFrame>();
    capture(CHECK, config, camera, &mut frame)?;
    let meta = frame.meta;
    for (which, got, declared) in [
        ("colour", meta.rgb_intrinsics, config.rgb_intrinsics),
        ("depth", meta.depth_intrinsics, config.depth_intrinsics),
    ] {
        if got != declared {
            return Err(violated(
                CHECK,
                format!("{which} intrinsics {got:?} differ from the declared {declared:?}"),
            ));
        }
    }
    if meta.is_color_only() != config.color_only {
        return Err(violated(
            CHECK,
            format!(
                "frame flagged colour only: {}, the camera is declared {}",
                meta.is_color_only(),
                if config.color_only {
                    "colour only"
                } else {
                    "with depth"
                }
            ),
        ));
    }
    intrinsics_sane("colour", &meta.rgb_intrinsics, RGB_WIDTH_PX, RGB_HEIGHT_PX)
        .and_then(|()| {
            intrinsics_sane(
                "depth",
                &meta.depth_intrinsics,
                DEPTH_WIDTH_PX,
                DEPTH_HEIGHT_PX,
            )
        })
        .and_then(|()| registration_rigid(&meta.color_from_depth, config.max_baseline_m))
        .map_err(|detail| violated(CHECK, detail))
}

/// Consecutive frames carry strictly increasing capture stamps, and every depth pixel is 0 or
/// within the valid range; at least one pixel has a return.
fn check_stream<C: RgbdCamera>(
    config: &CameraConformanceConfig,
    camera: &mut C,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "stamps_increase_and_depth_valid";
    let mut frame = boxed_zeroed::<RgbdFrame>();
    let [min_mm, max_mm] = config.valid_depth_mm;
    let mut last_stamp_ns = None;
    for index in 0..config.frames.max(2) {
        capture(CHECK, config, camera, &mut frame)?;
        let stamp_ns = frame.header.capture_ns;
        if stamp_ns == 0 || last_stamp_ns.is_some_and(|last| stamp_ns <= last) {
            return Err(violated(
                CHECK,
                format!("frame {index}: capture stamp {stamp_ns} ns after {last_stamp_ns:?}"),
            ));
        }
        last_stamp_ns = Some(stamp_ns);
        if frame.rgb.iter().all(|&byte| byte == frame.rgb[0]) {
            return Err(violated(
                CHECK,
                format!(
                    "frame {index}: the colour image is {} everywhere",
                    frame.rgb[0]
                ),
            ));
        }
        if config.color_only {
            if !frame.meta.is_color_only() {
                return Err(violated(
                    CHECK,
                    format!("frame {index} of a colour-only camera is not flagged so"),
                ));
            }
            if let Some(pixel) = frame.depth_mm.iter().position(|&depth_mm| depth_mm != 0) {
                return Err(violated(
                    CHECK,
                    format!(
                        "frame {index} of a colour-only camera has depth {} mm at pixel {pixel}",
                        frame.depth_mm[pixel]
                    ),
                ));
            }
            continue;
        }
        let mut returns = 0usize;
        for (pixel, &depth_mm) in frame.depth_mm.iter().enumerate() {
            if depth_mm == 0 {
                continue;
            }
            if !(min_mm..=max_mm).contains(&f64::from(depth_mm)) {
                return Err(violated(
                    CHECK,
                    format!(
                        "frame {index}: depth pixel ({}, {}) reads {depth_mm} mm, outside \
                         [{min_mm}, {max_mm}] mm and not 0",
                        pixel % DEPTH_WIDTH_PX,
                        pixel / DEPTH_WIDTH_PX
                    ),
                ));
            }
            returns += 1;
        }
        if returns == 0 {
            return Err(violated(
                CHECK,
                format!("frame {index} has no depth return at all"),
            ));
        }
    }
    Ok(())
}

/// A camera with nothing to deliver returns `Ok(false)` and writes nothing.
fn check_timeout<S: RgbdCamera>(
    config: &CameraConformanceConfig,
    camera: &mut S,
) -> Result<(), ConformanceError> {
    const CHECK: &str = "timeout_without_frame";
    let mut frame = boxed_zeroed::<RgbdFrame>();
    const SENTINEL_NS: u64 = 0x5EED;
    const SENTINEL_MM: u16 = 4242;
    frame.header.capture_ns = SENTINEL_NS;
    frame.depth_mm[0] = SENTINEL_MM;
    frame.rgb[0] = 7;
    let timeout = config.silent_timeout;
    for attempt in 0..2 {
        let captured = call(
            CHECK,
            || {
                format!(
                    "capture_into(frame, {} ms) on a silent camera",
                    timeout.as_millis()
                )
            },
            camera.capture_into(&mut frame, timeout),
        )?;
        if captured {
            return Err(violated(
                CHECK,
                format!("attempt {attempt}: a silent camera reported a frame"),
            ));
        }
        if frame.header.capture_ns != SENTINEL_NS
            || frame.depth_mm[0] != SENTINEL_MM
            || frame.rgb[0] != 7
        {
            return Err(violated(
                CHECK,
                format!("attempt {attempt}: a timed-out capture wrote into the buffer"),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::{DeviceError, ErrorKind};
    use harvest_ipc::payloads::RgbdFrameMeta;

    /// What a deliberately broken camera gets wrong.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Flaw {
        None,
        /// One depth pixel reads 100 mm (closer than the working range allows).
        DepthTooClose,
        /// Every frame carries the same stamp.
        RepeatsStamps,
        /// Reports the depth camera's intrinsics for colour.
        WrongIntrinsics,
        /// On timeout, stamps the caller's buffer anyway.
        WritesOnTimeout,
    }

    #[derive(Debug, thiserror::Error)]
    #[error("never")]
    struct Never;

    impl DeviceError for Never {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Other
        }
    }

    /// Frames of a flat wall at 1.5 m, or (silent) nothing.
    struct FakeCamera {
        silent: bool,
        stamp_ns: u64,
        flaw: Flaw,
    }

    impl RgbdCamera for FakeCamera {
        type Error = Never;

        fn capture_into(&mut self, frame: &mut RgbdFrame, _: Duration) -> Result<bool, Never> {
            if self.silent {
                if self.flaw == Flaw::WritesOnTimeout {
                    frame.header.capture_ns = 1;
                }
                return Ok(false);
            }
            if self.flaw != Flaw::RepeatsStamps {
                self.stamp_ns += 33_000_000;
            }
            frame.header.capture_ns = self.stamp_ns;
            frame.meta = RgbdFrameMeta {
                color_from_depth: RigidTransform::from_translation([-0.025, 0.0, 0.0]),
                ..RgbdFrameMeta::default()
            };
            if self.flaw == Flaw::WrongIntrinsics {
                frame.meta.rgb_intrinsics = CameraIntrinsics::tl460_depth();
            }
            frame.rgb[1] = 9;
            frame.depth_mm.fill(1500);
            frame.depth_mm[0] = 0;
            if self.flaw == Flaw::DepthTooClose {
                frame.depth_mm[1] = 100;
            }
            Ok(true)
        }
    }

    fn run(flaw: Flaw) -> Result<ConformanceReport, ConformanceError> {
        let camera = |silent| FakeCamera {
            silent,
            stamp_ns: 0,
            flaw,
        };
        conformance_suite(
            &CameraConformanceConfig::tl460(),
            || camera(false),
            || camera(true),
        )
    }

    fn failed_check(flaw: Flaw) -> &'static str {
        match run(flaw) {
            Err(ConformanceError::Violated { check, .. }) => check,
            other => panic!("{flaw:?}: expected a violation, got {other:?}"),
        }
    }

    #[test]
    fn a_good_camera_passes_and_broken_ones_fail_the_right_check() {
        let report = run(Flaw::None).expect("conforming camera");
        assert_eq!(report.checks_passed.len(), 3);
        assert_eq!(
            failed_check(Flaw::DepthTooClose),
            "stamps_increase_and_depth_valid"
        );
        assert_eq!(
            failed_check(Flaw::RepeatsStamps),
            "stamps_increase_and_depth_valid"
        );
        assert_eq!(failed_check(Flaw::WrongIntrinsics), "geometry_as_declared");
        assert_eq!(failed_check(Flaw::WritesOnTimeout), "timeout_without_frame");
    }

    #[test]
    fn a_tof_camera_declared_colour_only_fails_the_geometry_check() {
        let camera = |silent| FakeCamera {
            silent,
            stamp_ns: 0,
            flaw: Flaw::None,
        };
        let mut config = CameraConformanceConfig::color_only(CameraIntrinsics::tl460_rgb());
        config.depth_intrinsics = CameraIntrinsics::tl460_depth();
        config.max_baseline_m = 0.1;
        match conformance_suite(&config, || camera(false), || camera(true)) {
            Err(ConformanceError::Violated { check, detail }) => {
                assert_eq!(check, "geometry_as_declared");
                assert!(detail.contains("colour only"), "{detail}");
            }
            other => panic!("expected a violation, got {other:?}"),
        }
    }

    #[test]
    fn tl460_valid_depth_widens_the_range_by_four_sigma() {
        let config = CameraConformanceConfig::tl460();
        // 300 mm: sigma 4.75 mm; 9500 mm: sigma 27.75 mm.
        assert!((config.valid_depth_mm[0] - 281.0).abs() < 1e-9);
        assert!((config.valid_depth_mm[1] - 9611.0).abs() < 1e-9);
    }

    #[test]
    fn registration_check_accepts_a_short_translation_and_refuses_a_scaled_rotation() {
        let shifted = RigidTransform::from_translation([-0.025, 0.0, 0.0]);
        assert_eq!(registration_rigid(&shifted, 0.1), Ok(()));
        assert!(
            registration_rigid(&RigidTransform::from_translation([0.2, 0.0, 0.0]), 0.1).is_err()
        );
        let mut scaled = RigidTransform::IDENTITY;
        scaled.rotation[0][0] = 1.1;
        assert!(registration_rigid(&scaled, 0.1).is_err());
    }

    #[test]
    fn intrinsics_must_match_the_buffer() {
        let rgb = CameraIntrinsics::tl460_rgb();
        assert_eq!(
            intrinsics_sane("colour", &rgb, RGB_WIDTH_PX, RGB_HEIGHT_PX),
            Ok(())
        );
        assert!(intrinsics_sane("colour", &rgb, DEPTH_WIDTH_PX, DEPTH_HEIGHT_PX).is_err());
    }
}
