//! The error type of the in-process ALACS implementation and of the renderer, mapped to the
//! shared [`ErrorKind`]s. Other implementations (simulator over IPC, real driver) may reuse it.

use crate::error_kind::{DeviceError, ErrorKind};

/// Which part of the ALACS unit an error concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlacsPart {
    /// The linear slide carrying the laser.
    Slide,
    /// The red line laser.
    Laser,
    /// The RGB camera.
    Camera,
}

impl std::fmt::Display for AlacsPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Slide => "slide",
            Self::Laser => "laser",
            Self::Camera => "camera",
        })
    }
}

/// Failures of an ALACS unit or of rendering its image.
#[derive(Debug, thiserror::Error)]
pub enum AlacsError {
    /// The requested slide position is not finite or lies outside `[0, stroke]`; refused before
    /// reaching the hardware.
    #[error("slide position {requested_m} m is outside the stroke [0, {stroke_m}] m")]
    SlideOutOfStroke {
        /// The position asked for, metres from the home end.
        requested_m: f64,
        /// The slide's stroke, metres.
        stroke_m: f64,
    },
    /// The caller's RGB buffer does not hold exactly one `width x height x 3` image.
    #[error("RGB buffer holds {got_bytes} bytes, {width_px}x{height_px} RGB needs {needed_bytes}")]
    BufferSize {
        /// Bytes of the caller's buffer.
        got_bytes: usize,
        /// Bytes of one image.
        needed_bytes: usize,
        /// Image width, pixels.
        width_px: u32,
        /// Image height, pixels.
        height_px: u32,
    },
    /// A render input (scene object, parameter, intrinsics, extrinsics) is not usable; `what`
    /// names the field and its value.
    #[error("invalid ALACS render input: {what}")]
    InvalidInput {
        /// The field and its value.
        what: String,
    },
    /// The slide settled away from the requested position by more than its tolerance.
    #[error("slide settled at {actual_m} m instead of {requested_m} m (tolerance {tolerance_m} m)")]
    SlideMissedTarget {
        /// The position asked for, metres from the home end.
        requested_m: f64,
        /// Where the slide stopped, metres from the home end.
        actual_m: f64,
        /// The largest accepted difference, metres.
        tolerance_m: f64,
    },
    /// A part reported a fault (limit switch, drive alarm, laser interlock, sensor error).
    #[error("ALACS {part} fault: {detail}")]
    Fault {
        /// Which part failed.
        part: AlacsPart,
        /// The fault as the part reports it.
        detail: String,
    },
    /// A part is gone (cable, USB, simulator process).
    #[error("ALACS {part} disconnected: {detail}")]
    Disconnected {
        /// Which part failed.
        part: AlacsPart,
        /// What failed (the link's error).
        detail: String,
    },
    /// A part did not answer in time.
    #[error("ALACS {part} did not answer within {waited_ms} ms")]
    Timeout {
        /// Which part failed.
        part: AlacsPart,
        /// How long the driver waited, milliseconds.
        waited_ms: u64,
    },
    /// A part answered with something that could not be parsed.
    #[error("ALACS {part} protocol error: {detail}")]
    Protocol {
        /// Which part failed.
        part: AlacsPart,
        /// What could not be parsed.
        detail: String,
    },
}

impl DeviceError for AlacsError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::SlideOutOfStroke { .. } | Self::BufferSize { .. } | Self::InvalidInput { .. } => {
                ErrorKind::InvalidRequest
            }
            Self::SlideMissedTarget { .. } | Self::Fault { .. } => ErrorKind::Fault,
            Self::Disconnected { .. } => ErrorKind::Disconnected,
            Self::Timeout { .. } => ErrorKind::Timeout,
            Self::Protocol { .. } => ErrorKind::Protocol,
        }
    }
}
