//! Behaviour every [`AlacsUnit`] implementation must show, written once and generic over the
//! trait. Call [`check_all`] from each implementation's tests (simulated and real).

use crate::error_kind::{DeviceError, ErrorKind};

use super::{AlacsUnit, SLIDE_STROKE_M};

/// A conformance check that failed: which one and what was observed.
#[derive(Debug, thiserror::Error)]
#[error("ALACS conformance check `{check}` failed: {detail}")]
pub struct ConformanceFailure {
    /// The check's name.
    pub check: &'static str,
    /// What was observed instead of what the check expects.
    pub detail: String,
}

/// Slide positions are accepted over the whole stroke; the settled position is reported and
/// lies within 1 mm of the request.
pub fn check_slide_range<U: AlacsUnit>(unit: &mut U) -> Result<(), ConformanceFailure> {
    const CHECK: &str = "slide_range";
    for requested_m in [0.0, 0.05, 0.123, SLIDE_STROKE_M] {
        let settled_m = unit
            .move_slide(requested_m)
            .map_err(|e| ConformanceFailure {
                check: CHECK,
                detail: format!("move to {requested_m} m failed: {e}"),
            })?;
        let settled_close = (settled_m - requested_m).abs() <= 1e-3;
        if !settled_close {
            return Err(ConformanceFailure {
                check: CHECK,
                detail: format!("requested {requested_m} m, settled at {settled_m} m"),
            });
        }
    }
    Ok(())
}

/// Positions outside the stroke or not finite are refused with kind `InvalidRequest`, and the
/// slide keeps its previous position.
pub fn check_refuses_outside_stroke<U: AlacsUnit>(unit: &mut U) -> Result<(), ConformanceFailure> {
    const CHECK: &str = "refuses_outside_stroke";
    let fail = |detail: String| ConformanceFailure {
        check: CHECK,
        detail,
    };
    let before_m = unit
        .move_slide(0.1)
        .map_err(|e| fail(format!("move to 0.1 m failed: {e}")))?;
    for bad_m in [-0.01, SLIDE_STROKE_M + 0.01, f64::NAN, f64::INFINITY] {
        match unit.move_slide(bad_m) {
            Ok(settled_m) => {
                return Err(fail(format!(
                    "{bad_m} m accepted, settled at {settled_m} m"
                )));
            }
            Err(error) if error.kind() != ErrorKind::InvalidRequest => {
                return Err(fail(format!(
                    "{bad_m} m refused with kind {:?}: {error}",
                    error.kind()
                )));
            }
            Err(_) => {}
        }
    }
    let mut rgb = vec![0; image_len(unit)];
    let info = unit
        .capture_rgb(&mut rgb)
        .map_err(|e| fail(format!("capture failed: {e}")))?;
    if (info.slide_position_m - before_m).abs() > 1e-9 {
        return Err(fail(format!(
            "slide moved from {before_m} m to {} m after refused requests",
            info.slide_position_m
        )));
    }
    Ok(())
}

/// Captures fill a buffer of the intrinsics' size, report the laser state and the settled
/// slide position, and refuse a wrongly sized buffer with kind `InvalidRequest`.
pub fn check_capture<U: AlacsUnit>(unit: &mut U) -> Result<(), ConformanceFailure> {
    const CHECK: &str = "capture";
    let fail = |detail: String| ConformanceFailure {
        check: CHECK,
        detail,
    };
    let settled_m = unit
        .move_slide(0.02)
        .map_err(|e| fail(format!("move failed: {e}")))?;
    let mut rgb = vec![0; image_len(unit)];
    let mut last_stamp_ns = None;
    for laser_on in [true, false] {
        unit.set_laser(laser_on)
            .map_err(|e| fail(format!("set_laser({laser_on}) failed: {e}")))?;
        let info = unit
            .capture_rgb(&mut rgb)
            .map_err(|e| fail(format!("capture failed: {e}")))?;
        if info.laser_on != laser_on || info.slide_position_m != settled_m {
            return Err(fail(format!(
                "frame info {info:?} does not match laser {laser_on}, slide {settled_m} m"
            )));
        }
        if info.intrinsics != unit.intrinsics() {
            return Err(fail("frame intrinsics differ from the unit's".into()));
        }
        if last_stamp_ns.is_some_and(|last| info.stamp_ns <= last) {
            return Err(fail(format!(
                "stamps not increasing: {last_stamp_ns:?} then {}",
                info.stamp_ns
            )));
        }
        last_stamp_ns = Some(info.stamp_ns);
    }
    let mut short = vec![0; rgb.len().saturating_sub(3)];
    match unit.capture_rgb(&mut short) {
        Err(error) if error.kind() == ErrorKind::InvalidRequest => Ok(()),
        Err(error) => Err(fail(format!(
            "short buffer refused with kind {:?}",
            error.kind()
        ))),
        Ok(_) => Err(fail("short buffer accepted".into())),
    }
}

/// Runs every check in turn, stopping at the first failure; leaves the laser off.
pub fn check_all<U: AlacsUnit>(unit: &mut U) -> Result<(), ConformanceFailure> {
    check_slide_range(unit)?;
    check_refuses_outside_stroke(unit)?;
    check_capture(unit)?;
    unit.set_laser(false).map_err(|e| ConformanceFailure {
        check: "laser_off",
        detail: e.to_string(),
    })
}

fn image_len<U: AlacsUnit>(unit: &U) -> usize {
    let intrinsics = unit.intrinsics();
    intrinsics.width_px as usize * intrinsics.height_px as usize * 3
}
