//! Type erasure for valve boards: one error type ([`AnyDeviceError`], which keeps the kind) for
//! every implementation, so a process can hold `Box<dyn ValveBoard<Error = AnyDeviceError>>` and pick
//! the real driver or a simulated board at start-up.

use super::{BoardFault, Heartbeat, PressureReadings, ValveBoard, ValveId, ValveStates};
use crate::error_kind::AnyDeviceError;

/// A valve board behind a trait object with a boxed error.
pub type DynValveBoard = Box<dyn ValveBoard<Error = AnyDeviceError> + Send>;

/// Wraps any board so its errors become [`AnyDeviceError`].
#[derive(Debug)]
pub struct ErasedValveBoard<B>(pub B);

impl<B: ValveBoard + Send + 'static> ErasedValveBoard<B> {
    /// Box `board` as a [`DynValveBoard`].
    pub fn boxed(board: B) -> DynValveBoard {
        Box::new(ErasedValveBoard(board))
    }
}

impl<B: ValveBoard> ValveBoard for ErasedValveBoard<B> {
    type Error = AnyDeviceError;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        self.0.set_valve(valve, open).map_err(AnyDeviceError::new)
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        self.0.valve_states().map_err(AnyDeviceError::new)
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        self.0.pressures().map_err(AnyDeviceError::new)
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        self.0.close_all().map_err(AnyDeviceError::new)
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        self.0.ping().map_err(AnyDeviceError::new)
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        self.0.take_faults()
    }
}
