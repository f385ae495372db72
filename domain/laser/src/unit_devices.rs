//! The ALACS unit as the laser node's devices ([`UnitDevices`], `harvest_node::Devices`): a
//! tick's command is at most one exchange ([`crate::interval_scan::exchange`]), its answer is
//! the next tick's reading ([`UnitReading`]), and the safe state is the laser off.
//!
//! - **Stop** (the emergency stop, the end of the run): the laser off, skipped when the unit
//!   confirmed it off and nothing was written since.
//! - **Hold** (after a refused exchange): nothing more in that tick, so that a tick never
//!   waits for two exchanges; the scan's own failure path switches the laser off at the next
//!   tick ([`crate::interval_scan::IntervalScan::failed`]).
//! - **Read**: the answer to the last exchange, taken once; no exchange of its own, so it
//!   never fails.
//!
//! A captured image stays in one buffer shared with the reading that carries it (never
//! copied): a capture always follows a move, whose reading holds no image, so the buffer is
//! unshared again when the next capture is written into it.

use std::sync::Arc;
use std::time::Instant;

use harvest_hw::alacs::AlacsUnit;
use harvest_hw::{DeviceError, ErrorKind};
use harvest_node::Devices;

use crate::interval_scan::{UnitAnswer, UnitExchange, exchange, rgb_len};

/// A failed exchange as the node sees it (the runtime logs and counts the unit's own error).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message} ({kind})")]
pub struct UnitFailure {
    pub kind: ErrorKind,
    pub message: String,
}

impl UnitFailure {
    pub fn new(error: &impl DeviceError) -> Self {
        Self {
            kind: error.kind(),
            message: error.to_string(),
        }
    }
}

impl DeviceError for UnitFailure {
    fn kind(&self) -> ErrorKind {
        self.kind
    }
}

/// The unit's answer to the last exchange.
#[derive(Debug, Clone)]
pub struct UnitReading {
    /// What the unit answered, or why the exchange failed.
    pub outcome: Result<UnitAnswer, UnitFailure>,
    /// Wall time spent in the exchange, ns.
    pub device_ns: u64,
    /// The captured image of a capture's answer.
    image: Option<Arc<Vec<u8>>>,
}

impl UnitReading {
    /// The captured image (empty unless the exchange was a capture).
    pub fn image(&self) -> &[u8] {
        self.image.as_deref().map_or(&[], Vec::as_slice)
    }
}

/// The ALACS unit `U` driven one exchange per tick (module documentation).
#[derive(Debug)]
pub struct UnitDevices<U> {
    unit: U,
    image: Arc<Vec<u8>>,
    reading: Option<UnitReading>,
    /// The unit confirmed the laser off and nothing was written since.
    laser_off: bool,
}

impl<U: AlacsUnit> UnitDevices<U> {
    /// The devices of `unit`, with a buffer of one image of its camera.
    pub fn new(unit: U) -> Self {
        let image = Arc::new(vec![0; rgb_len(&unit.intrinsics())]);
        Self {
            unit,
            image,
            reading: None,
            laser_off: false,
        }
    }

    pub fn unit(&self) -> &U {
        &self.unit
    }
}

impl<U: AlacsUnit> Devices for UnitDevices<U> {
    type Readings = UnitReading;
    type Commands = Option<UnitExchange>;
    type Error = U::Error;

    /// The laser off (module documentation).
    fn stop(&mut self) -> Result<(), U::Error> {
        if self.laser_off {
            return Ok(());
        }
        self.unit.set_laser(false)?;
        self.laser_off = true;
        Ok(())
    }

    /// Nothing (module documentation).
    fn hold(&mut self) -> Result<(), U::Error> {
        Ok(())
    }

    fn read(&mut self, _now_ns: u64) -> Result<Option<UnitReading>, U::Error> {
        Ok(self.reading.take())
    }

    /// Makes the exchange, if any; its answer (or failure) is the next reading.
    fn write(&mut self, command: &Option<UnitExchange>) -> Result<(), U::Error> {
        let Some(next) = *command else {
            return Ok(());
        };
        self.laser_off = false;
        let started = Instant::now();
        // Only a capture writes into the image (unshared by then: no copy).
        let rgb: &mut [u8] = match next {
            UnitExchange::Capture => Arc::make_mut(&mut self.image).as_mut_slice(),
            UnitExchange::SetLaser(_) | UnitExchange::MoveSlide(_) => &mut [],
        };
        let result = exchange(&mut self.unit, next, rgb);
        let device_ns = started.elapsed().as_nanos() as u64;
        let (outcome, image, written) = match result {
            Ok(answer) => {
                self.laser_off = next == UnitExchange::SetLaser(false);
                let image =
                    matches!(answer, UnitAnswer::Captured { .. }).then(|| Arc::clone(&self.image));
                (Ok(answer), image, Ok(()))
            }
            Err(error) => (Err(UnitFailure::new(&error)), None, Err(error)),
        };
        self.reading = Some(UnitReading {
            outcome,
            device_ns,
            image,
        });
        written
    }
}
