//! The devices of a re-run control node: they answer each tick what the live devices answered
//! ([`NodeTickRecord`]: the readings, a failed read, a refused command). The arm's servos
//! ([`RecordedServos`]) and the valve board ([`RecordedBoard`]) implement the same driver
//! traits as the real ones, so the node and its runtime glue run unchanged.

use harvest_arm::node::EncoderSample;
use harvest_arm::task::ArmDevices;
use harvest_hw::arm_servos::{ArmServos, JOINT_COUNT, JointFeedback};
use harvest_hw::valve_board::{
    BoardFault, Heartbeat, PressureReadings, ValveBoard, ValveId, ValveState, ValveStates,
};
use harvest_hw::{DeviceError, ErrorKind};
use harvest_ipc::codec::decode_exact;
use harvest_ipc::payloads::{DeviceErrorCode, DeviceRead, NodeTickRecord};
use harvest_vacuum::node::BoardReadings;
use harvest_vacuum::task::BoardDevices;

/// A device failure as the recording says it happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("recorded device failure ({0})")]
pub struct RecordedFailure(pub ErrorKind);

impl DeviceError for RecordedFailure {
    fn kind(&self) -> ErrorKind {
        self.0
    }
}

fn kind_of(code: Option<DeviceErrorCode>) -> ErrorKind {
    match code {
        Some(DeviceErrorCode::Disconnected) => ErrorKind::Disconnected,
        Some(DeviceErrorCode::Timeout) => ErrorKind::Timeout,
        Some(DeviceErrorCode::Fault) => ErrorKind::Fault,
        Some(DeviceErrorCode::Protocol) => ErrorKind::Protocol,
        Some(DeviceErrorCode::Refused) => ErrorKind::InvalidRequest,
        Some(DeviceErrorCode::None | DeviceErrorCode::Other) | None => ErrorKind::Other,
    }
}

/// One tick's answers, decoded from its record.
#[derive(Debug, Clone, Copy)]
struct Answers<R> {
    read: Result<Option<R>, ErrorKind>,
    /// The first command exchange of the tick fails with this (the live devices refused the
    /// tick's commands); taken by that exchange.
    write_refused: Option<ErrorKind>,
}

impl<R> Default for Answers<R> {
    fn default() -> Self {
        Self {
            read: Ok(None),
            write_refused: None,
        }
    }
}

/// Why a record's readings cannot be given to the node.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("tick {tick}: the recorded device readings do not decode ({reason})")]
pub struct UnreadableReadings {
    pub tick: u64,
    pub reason: String,
}

impl<R: serde::de::DeserializeOwned> Answers<R> {
    fn of(record: &NodeTickRecord) -> Result<Self, UnreadableReadings> {
        let read = match record.device_read.get().ok() {
            Some(DeviceRead::Readings) => Ok(Some(
                decode_exact::<R>(record.readings.as_slice()).map_err(|error| {
                    UnreadableReadings {
                        tick: record.tick,
                        reason: error.to_string(),
                    }
                })?,
            )),
            Some(DeviceRead::Nothing) => Ok(None),
            Some(DeviceRead::TooLarge) => {
                return Err(UnreadableReadings {
                    tick: record.tick,
                    reason: "the live readings did not fit the record".to_owned(),
                });
            }
            Some(DeviceRead::Failed) | None => Err(kind_of(record.read_error.get().ok())),
        };
        let write_refused = match record.write_error.get().ok() {
            Some(DeviceErrorCode::None) => None,
            other => Some(kind_of(other)),
        };
        Ok(Self {
            read,
            write_refused,
        })
    }

    fn take_write(&mut self) -> Result<(), RecordedFailure> {
        self.write_refused
            .take()
            .map_or(Ok(()), |kind| Err(RecordedFailure(kind)))
    }
}

/// A re-run node's devices: told each tick what to answer.
pub trait RecordedDevices {
    fn answer(&mut self, record: &NodeTickRecord) -> Result<(), UnreadableReadings>;
}

/// An arm's servos answering from the recording.
#[derive(Debug, Default)]
pub struct RecordedServos {
    answers: Answers<EncoderSample>,
}

impl ArmServos for RecordedServos {
    type Error = RecordedFailure;

    fn command(
        &mut self,
        _position: [f64; JOINT_COUNT],
        _velocity: [f64; JOINT_COUNT],
    ) -> Result<(), RecordedFailure> {
        self.answers.take_write()
    }

    fn hold(&mut self) -> Result<(), RecordedFailure> {
        self.answers.take_write()
    }

    fn feedback(&mut self) -> Result<Option<JointFeedback>, RecordedFailure> {
        self.answers.read.map_err(RecordedFailure).map(|sample| {
            sample.map(|sample| JointFeedback {
                capture_ns: sample.capture_ns,
                position: sample.position,
                velocity: sample.velocity,
                fault_bits: 0,
            })
        })
    }
}

impl RecordedDevices for ArmDevices<RecordedServos> {
    fn answer(&mut self, record: &NodeTickRecord) -> Result<(), UnreadableReadings> {
        self.0.answers = Answers::of(record)?;
        Ok(())
    }
}

/// The valve board answering from the recording. A tick whose commands the live board refused
/// fails its first command exchange only (the live board may have refused more of them, and a
/// refused safe-state exchange is not recorded): the devices' own cache of what was sent may
/// then differ from the live one's, and with it which later exchanges are made; the vacuum
/// supervisor's outputs do not depend on it (a refusal is only logged), and each tick's reads
/// are the recorded ones.
#[derive(Debug, Default)]
pub struct RecordedBoard {
    answers: Answers<BoardReadings>,
}

impl RecordedBoard {
    fn readings(&self) -> Result<BoardReadings, RecordedFailure> {
        match self.answers.read {
            Ok(Some(readings)) => Ok(readings),
            // The board always answers when it answers: a tick without readings is a
            // failed one.
            Ok(None) => Err(RecordedFailure(ErrorKind::Other)),
            Err(kind) => Err(RecordedFailure(kind)),
        }
    }
}

impl ValveBoard for RecordedBoard {
    type Error = RecordedFailure;

    fn set_valve(&mut self, _valve: ValveId, _open: bool) -> Result<(), RecordedFailure> {
        self.answers.take_write()
    }

    fn valve_states(&mut self) -> Result<ValveStates, RecordedFailure> {
        let readings = self.readings()?;
        Ok(ValveStates(std::array::from_fn(|k| {
            match (readings.valve_open[k], readings.valve_in_transit[k]) {
                (true, true) => ValveState::Opening,
                (true, false) => ValveState::Open,
                (false, true) => ValveState::Closing,
                (false, false) => ValveState::Closed,
            }
        })))
    }

    fn pressures(&mut self) -> Result<PressureReadings, RecordedFailure> {
        let [arm1, arm2, source] = self.readings()?.pressure_mmh2o;
        Ok(PressureReadings {
            arm1_vacuum_mmh2o: arm1,
            arm2_vacuum_mmh2o: arm2,
            source_vacuum_mmh2o: source,
        })
    }

    fn close_all(&mut self) -> Result<(), RecordedFailure> {
        self.answers.take_write()
    }

    fn ping(&mut self) -> Result<Heartbeat, RecordedFailure> {
        Ok(Heartbeat { board_uptime_ms: 0 })
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        Vec::new()
    }
}

impl RecordedDevices for BoardDevices<RecordedBoard> {
    fn answer(&mut self, record: &NodeTickRecord) -> Result<(), UnreadableReadings> {
        self.board_mut().answers = Answers::of(record)?;
        Ok(())
    }
}
