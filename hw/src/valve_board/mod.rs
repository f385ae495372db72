//! Valve board: 4 butterfly valves and 3 pressure sensors behind one controller.
//!
//! The real board is an Arduino on a serial line ([dual-arm sec. 2.3]): it drives the four
//! butterfly gates that route the shared vacuum source to either arm or to atmosphere, and it
//! samples the pressure inside each arm and at the source.
//!
//! - [`ValveBoard`]: the device trait every implementation provides.
//! - [`types`]: plain data ([`ValveId`], [`ValveState`], [`PressureReadings`], ...).
//! - [`protocol`] and [`line_assembler`]: the serial line protocol (see `hw/VALVE_PROTOCOL.md`).
//! - [`serial`]: the driver for the real board.
//! - [`fake_board`]: a fake board on a pseudo-terminal, with fault injection (always compiled
//!   on Unix, no cargo feature, so other crates' tests can use it).
//! - [`conformance`]: the behaviour every implementation must show, generic over the trait.
//! - [`dyn_board`]: a type-erased board for `Box<dyn ValveBoard<...>>` use.

#[cfg(any(test, feature = "testing"))]
pub mod conformance;
pub mod dyn_board;
#[cfg(unix)]
#[cfg(any(test, feature = "testing"))]
pub mod fake_board;
pub mod line_assembler;
pub mod protocol;
pub mod serial;
pub mod sim;
pub mod types;

pub use dyn_board::{DynValveBoard, ErasedValveBoard};
pub use serial::{SerialBoardConfig, SerialBoardError, SerialValveBoard};
pub use types::{
    BoardFault, Heartbeat, PressureReadings, PressureSensor, VALVE_COUNT, ValveId, ValveState,
    ValveStates,
};

use crate::error_kind::DeviceError;

/// A valve board: four butterfly valves (1-2 serve arm 1, 3-4 serve arm 2) and three pressure
/// sensors (inside arm 1, inside arm 2, at the source).
///
/// Meant for a single-threaded process loop: every method takes `&mut self`, does one bounded
/// exchange with the board and returns. The trait is object safe (`dyn ValveBoard<Error = E>`);
/// wrap a board in [`ErasedValveBoard`] to get one error type for any implementation.
///
/// Physical caveats every caller must respect:
/// - **Actuation delay.** [`ValveBoard::set_valve`] returns once the board has *accepted* the
///   command; the gate then takes up to [`types::VALVE_ACTUATION_MAX_MS`] (under 1 s) to reach
///   its end stop. Until then [`ValveBoard::valve_states`] reports `Opening`/`Closing` and the
///   arm pressure is in between. Wait for the end state before inferring anything from
///   pressure.
/// - **Sensor noise.** Pressure samples carry ADC quantisation (a few mmH2O) and flow ripple;
///   filter them or threshold with margin. Pressure also lags valve motion because the tube
///   volume has to fill or empty.
/// - **Shared source.** Opening both arms to the source at once without a sealed end-effector
///   drops the vacuum available to each ([dual-arm sec. 3.3]); this trait does not enforce
///   the coordination policy, the vacuum process does.
pub trait ValveBoard {
    /// The implementation's error; its [`DeviceError::kind`] is what generic code reacts to.
    type Error: DeviceError;

    /// Command `valve` to open (`open = true`) or close. Idempotent: commanding the position
    /// the valve already has (or is moving to) changes nothing.
    ///
    /// Returns once the board accepted the command, not once the gate arrived. An id outside
    /// 1..=4 fails with kind `InvalidRequest` without reaching the hardware; a valve the board
    /// reports stuck fails with kind `Fault`.
    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error>;

    /// Read where every valve is, including which ones are still moving.
    fn valve_states(&mut self) -> Result<ValveStates, Self::Error>;

    /// Read the three pressure sensors (vacuum in mmH2O, positive below atmosphere).
    fn pressures(&mut self) -> Result<PressureReadings, Self::Error>;

    /// Emergency: command every valve closed in one request. Returns once the board accepted
    /// it; the gates still take up to one actuation time to close. With all four gates closed
    /// each arm is cut off from both the source and atmosphere, so an attached apple is held
    /// only by the residual vacuum in the tube until it leaks away.
    fn close_all(&mut self) -> Result<(), Self::Error>;

    /// Heartbeat: a round trip to the board that proves its firmware is running.
    fn ping(&mut self) -> Result<Heartbeat, Self::Error>;

    /// Faults the board reported on its own since the last call (received while doing other
    /// requests), oldest first. Does not talk to the board.
    fn take_faults(&mut self) -> Vec<BoardFault>;
}

impl<B: ValveBoard + ?Sized> ValveBoard for Box<B> {
    type Error = B::Error;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        (**self).set_valve(valve, open)
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        (**self).valve_states()
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        (**self).pressures()
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        (**self).close_all()
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        (**self).ping()
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        (**self).take_faults()
    }
}
