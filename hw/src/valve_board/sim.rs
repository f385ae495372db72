//! The simulated valve board as a device: valve commands go out on `hw/valves/command`, the
//! board's readings (valve positions, in-transit flags, 3 pressures) come back on
//! `hw/valves/readings`, served by the simulator at its physics rate.

use super::types::{Heartbeat, PressureReadings, VALVE_COUNT, ValveId, ValveState, ValveStates};
use super::{BoardFault, ValveBoard};
use crate::error_kind::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::{HW_VALVE_COMMAND, HW_VALVE_READINGS};
use harvest_ipc::error::IpcError;
use harvest_ipc::payloads::{ValveBoardCommand, ValveBoardReadings};
use harvest_ipc::{Context, MonotonicClock, Publisher, Subscriber};
use std::time::Duration;

/// Errors of the simulated valve board link.
#[derive(Debug, thiserror::Error)]
pub enum SimValveBoardError {
    /// Valve id outside 1..=4; nothing was sent.
    #[error("invalid valve id {0} (valves are 1..=4)")]
    InvalidValve(u8),
    /// The simulated board has not answered within the timeout.
    #[error(
        "simulated valve board did not report within {timeout_ms} ms (is the sim process running?)"
    )]
    Silent {
        /// How long the driver waited, milliseconds.
        timeout_ms: u64,
    },
    /// The hardware channel failed.
    #[error("simulated valve board link: {0}")]
    Link(#[from] IpcError),
}

impl DeviceError for SimValveBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::InvalidValve(_) => ErrorKind::InvalidRequest,
            Self::Silent { .. } => ErrorKind::Timeout,
            Self::Link(_) => ErrorKind::Disconnected,
        }
    }
}

/// Driver for the simulated valve board.
pub struct SimValveBoard {
    commands: Publisher<ValveBoardCommand>,
    readings: Subscriber<ValveBoardReadings>,
    commanded_open: [bool; VALVE_COUNT],
    latest: Option<ValveBoardReadings>,
    first_reading_ns: Option<u64>,
    timeout: Duration,
}

impl SimValveBoard {
    /// Connects; requests wait up to `timeout` for the board's first reading.
    pub fn connect(context: &Context, timeout: Duration) -> Result<Self, SimValveBoardError> {
        let link =
            |error: harvest_ipc::error::OpenChannelError| SimValveBoardError::Link(error.into());
        Ok(Self {
            commands: context.publisher(HW_VALVE_COMMAND).map_err(link)?,
            readings: context.subscriber(HW_VALVE_READINGS).map_err(link)?,
            commanded_open: [false; VALVE_COUNT],
            latest: None,
            first_reading_ns: None,
            timeout,
        })
    }

    fn send_commands(&mut self) -> Result<(), SimValveBoardError> {
        let valve_open = self.commanded_open.map(u8::from);
        self.commands
            .publish_with(MonotonicClock::read_ns(), |command| {
                command.valve_open = valve_open;
                command._reserved = [0; 4];
            })
            .map_err(|error| SimValveBoardError::Link(error.into()))?;
        Ok(())
    }

    /// The newest reading; waits (event-driven, bounded) for the first one.
    fn refresh(&mut self) -> Result<ValveBoardReadings, SimValveBoardError> {
        let receive = |readings: &Subscriber<ValveBoardReadings>| {
            readings
                .receive_latest()
                .map(|sample| sample.map(|reading| *reading))
                .map_err(|error| SimValveBoardError::Link(error.into()))
        };
        if let Some(reading) = receive(&self.readings)? {
            self.latest = Some(reading);
        }
        if self.latest.is_none() {
            let _ = self.readings.listener().timed_wait(|_| {}, self.timeout);
            self.latest = receive(&self.readings)?;
        }
        let reading = self.latest.ok_or(SimValveBoardError::Silent {
            timeout_ms: self.timeout.as_millis() as u64,
        })?;
        self.first_reading_ns
            .get_or_insert(reading.header.capture_ns);
        Ok(reading)
    }
}

impl ValveBoard for SimValveBoard {
    type Error = SimValveBoardError;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        let index = valve
            .index()
            .ok_or(SimValveBoardError::InvalidValve(valve.0))?;
        self.commanded_open[index] = open;
        self.send_commands()
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        let reading = self.refresh()?;
        let mut states = [ValveState::Closed; VALVE_COUNT];
        for (index, state) in states.iter_mut().enumerate() {
            let commanded = self.commanded_open[index];
            let at_commanded_stop = reading.valve_in_transit[index] == 0
                && (reading.valve_open[index] != 0) == commanded;
            // A command the board accepted but has not acted on yet (still on its way over the
            // link) is reported as travel toward it, as the real board does once it accepted it.
            *state = match (at_commanded_stop, commanded) {
                (true, open) => ValveState::settled(open),
                (false, true) => ValveState::Opening,
                (false, false) => ValveState::Closing,
            };
        }
        Ok(ValveStates(states))
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        Ok(PressureReadings::from_array(self.refresh()?.pressure_mmh2o))
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        self.commanded_open = [false; VALVE_COUNT];
        self.send_commands()
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        let reading = self.refresh()?;
        let since_first_ns = reading
            .header
            .capture_ns
            .saturating_sub(self.first_reading_ns.unwrap_or(0));
        Ok(Heartbeat {
            board_uptime_ms: (since_first_ns / 1_000_000) as u32,
        })
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error_kind::lost_link;

    #[test]
    fn every_error_maps_to_its_kind() {
        assert_eq!(
            SimValveBoardError::InvalidValve(9).kind(),
            ErrorKind::InvalidRequest
        );
        assert_eq!(
            SimValveBoardError::Silent { timeout_ms: 500 }.kind(),
            ErrorKind::Timeout
        );
        assert_eq!(
            SimValveBoardError::from(lost_link()).kind(),
            ErrorKind::Disconnected
        );
    }
}
