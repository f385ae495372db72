//! The error kinds every device implementation maps its own errors to, so generic code (the
//! supervisor, a process's recovery logic) can react to the kind alone.

/// What kind of failure a device reported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// The device is gone (cable, USB, serial port closed, simulator process dead).
    Disconnected,
    /// The device did not answer in time.
    Timeout,
    /// The device answered but reported a fault (over-current, limit switch, sensor error).
    Fault,
    /// The device answered with something we could not parse (framing, checksum, garbage).
    Protocol,
    /// The request was refused before reaching the device (out of range, NaN, wrong state).
    InvalidRequest,
    /// Anything else.
    Other,
}

/// Implemented by every device error type.
pub trait DeviceError: std::error::Error + Send + Sync + 'static {
    fn kind(&self) -> ErrorKind;
}
