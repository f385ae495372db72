//! The error kinds every device implementation maps its own errors to, so generic code (the
//! supervisor, a process's recovery logic, the health channel) can react to the kind alone.

use harvest_ipc::payloads::DeviceErrorCode;

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
    /// The request was refused before reaching the device (out of range, NaN, wrong state), or
    /// the device refused it as such.
    InvalidRequest,
    /// Anything else.
    Other,
}

impl ErrorKind {
    /// The kind's name as logs and status lines print it (`timeout`, `refused`, ...); the same
    /// names as [`DeviceErrorCode::name`].
    pub fn name(self) -> &'static str {
        DeviceErrorCode::from(self).name()
    }
}

impl std::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The code a heartbeat carries for this kind
/// ([`harvest_ipc::payloads::ProcessHealth::last_device_error`]).
impl From<ErrorKind> for DeviceErrorCode {
    fn from(kind: ErrorKind) -> Self {
        match kind {
            ErrorKind::Disconnected => Self::Disconnected,
            ErrorKind::Timeout => Self::Timeout,
            ErrorKind::Fault => Self::Fault,
            ErrorKind::Protocol => Self::Protocol,
            ErrorKind::InvalidRequest => Self::Refused,
            ErrorKind::Other => Self::Other,
        }
    }
}

/// Implemented by every device error type.
pub trait DeviceError: std::error::Error + Send + Sync + 'static {
    /// What kind of failure this is; generic code decides on it (retry a timeout, restart on a
    /// disconnect, stop on a fault, report a refusal).
    fn kind(&self) -> ErrorKind;
}

/// Devices that cannot fail (a node without devices).
impl DeviceError for std::convert::Infallible {
    fn kind(&self) -> ErrorKind {
        match *self {}
    }
}

/// The error of any driver, boxed, with its kind: what a process (or a type-erased driver such as
/// [`crate::valve_board::DynValveBoard`]) keeps when it passes a device error on without naming
/// the driver's type.
#[derive(Debug)]
pub struct AnyDeviceError {
    kind: ErrorKind,
    inner: Box<dyn DeviceError>,
}

impl std::fmt::Display for AnyDeviceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.inner, self.kind)
    }
}

impl std::error::Error for AnyDeviceError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        let inner: &(dyn std::error::Error + 'static) = self.inner.as_ref();
        Some(inner)
    }
}

impl AnyDeviceError {
    /// Wraps a driver's error, keeping its kind.
    pub fn new(error: impl DeviceError) -> Self {
        Self {
            kind: error.kind(),
            inner: Box::new(error),
        }
    }

    /// The driver's error.
    pub fn inner(&self) -> &(dyn DeviceError + 'static) {
        self.inner.as_ref()
    }
}

impl DeviceError for AnyDeviceError {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

/// A lost hardware channel, for the drivers' error-mapping tests.
#[cfg(test)]
pub(crate) fn lost_link() -> harvest_ipc::error::IpcError {
    harvest_ipc::error::WaitError {
        reason: "the simulator's node is gone".to_owned(),
    }
    .into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_has_its_own_heartbeat_code() {
        let kinds = [
            ErrorKind::Disconnected,
            ErrorKind::Timeout,
            ErrorKind::Fault,
            ErrorKind::Protocol,
            ErrorKind::InvalidRequest,
            ErrorKind::Other,
        ];
        let codes: std::collections::HashSet<DeviceErrorCode> = kinds
            .iter()
            .map(|kind| DeviceErrorCode::from(*kind))
            .collect();
        assert_eq!(codes.len(), kinds.len());
        assert!(!codes.contains(&DeviceErrorCode::None));
        assert_eq!(ErrorKind::InvalidRequest.to_string(), "refused");
        assert_eq!(ErrorKind::Timeout.to_string(), "timeout");
    }

    #[derive(Debug, thiserror::Error)]
    #[error("no answer")]
    struct Silent;
    impl DeviceError for Silent {
        fn kind(&self) -> ErrorKind {
            ErrorKind::Timeout
        }
    }

    #[test]
    fn a_wrapped_error_keeps_its_kind_and_text() {
        let wrapped = AnyDeviceError::new(Silent);
        assert_eq!(wrapped.kind(), ErrorKind::Timeout);
        assert_eq!(wrapped.to_string(), "no answer (timeout)");
        assert!(std::error::Error::source(&wrapped).is_some());
    }
}
