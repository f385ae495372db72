//! Type erasure for valve boards: one error type ([`BoxedBoardError`]) for every
//! implementation, so a process can hold `Box<dyn ValveBoard<Error = BoxedBoardError>>` and pick
//! the real driver or a simulated board at start-up.

use super::{BoardFault, Heartbeat, PressureReadings, ValveBoard, ValveId, ValveStates};
use crate::error_kind::{DeviceError, ErrorKind};
use std::fmt;

/// A valve board behind a trait object with a boxed error.
pub type DynValveBoard = Box<dyn ValveBoard<Error = BoxedBoardError> + Send>;

/// Any implementation's error, boxed; keeps the original error as its source and its kind.
#[derive(Debug)]
pub struct BoxedBoardError {
    kind: ErrorKind,
    inner: Box<dyn DeviceError>,
}

impl BoxedBoardError {
    /// Box an implementation's error.
    pub fn new<E: DeviceError>(error: E) -> BoxedBoardError {
        BoxedBoardError {
            kind: error.kind(),
            inner: Box::new(error),
        }
    }

    /// The original error.
    pub fn inner(&self) -> &(dyn DeviceError + 'static) {
        self.inner.as_ref()
    }
}

impl fmt::Display for BoxedBoardError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.inner, f)
    }
}

impl std::error::Error for BoxedBoardError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.inner.source()
    }
}

impl DeviceError for BoxedBoardError {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

/// Wraps any board so its errors become [`BoxedBoardError`].
#[derive(Debug)]
pub struct ErasedValveBoard<B>(pub B);

impl<B: ValveBoard + Send + 'static> ErasedValveBoard<B> {
    /// Box `board` as a [`DynValveBoard`].
    pub fn boxed(board: B) -> DynValveBoard {
        Box::new(ErasedValveBoard(board))
    }
}

impl<B: ValveBoard> ValveBoard for ErasedValveBoard<B> {
    type Error = BoxedBoardError;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        self.0.set_valve(valve, open).map_err(BoxedBoardError::new)
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        self.0.valve_states().map_err(BoxedBoardError::new)
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        self.0.pressures().map_err(BoxedBoardError::new)
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        self.0.close_all().map_err(BoxedBoardError::new)
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        self.0.ping().map_err(BoxedBoardError::new)
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        self.0.take_faults()
    }
}
