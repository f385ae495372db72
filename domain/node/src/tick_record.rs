//! What a tick saw, written down as it happens ([`TickRecorder`], kept by the
//! [`crate::Runner`] when asked): the stop and mode samples read, the device read's outcome
//! and readings, the stamps of every input message, and whether the devices refused the
//! commands. A runtime publishes the record after the tick (`arm1/ticks`, ...), so a recording
//! holds everything the node decided from ([`NodeTickRecord`]).

use harvest_hw::ErrorKind;
use harvest_ipc::Payload;
use harvest_ipc::catalogue::Channel;
use harvest_ipc::codec::{CodecError, encode_into};
use harvest_ipc::payloads::{
    DeviceErrorCode, DeviceRead, MODE_SLOT, NodeTickRecord, OperatorModeState, StopHeard, TickInput,
};

use crate::in_place::LatestInPlace;
use crate::ports::{Drain, Latest};
use crate::transport::{InputVisitor, Inputs};

/// Encodes one tick's readings into the record's bytes.
type EncodeReadings<R> = fn(&R, &mut Vec<u8>) -> Result<(), CodecError>;

/// Builds one [`NodeTickRecord`] per tick (module documentation).
pub struct TickRecorder<R> {
    encode: EncodeReadings<R>,
    record: NodeTickRecord,
    scratch: Vec<u8>,
}

impl<R: serde::Serialize> TickRecorder<R> {
    /// A recorder of readings of type `R`, encoded by the codec.
    pub fn new() -> Self {
        Self {
            encode: |readings, out| encode_into(readings, out),
            record: NodeTickRecord::default(),
            scratch: Vec::new(),
        }
    }
}

impl<R: serde::Serialize> Default for TickRecorder<R> {
    fn default() -> Self {
        Self::new()
    }
}

impl<R> TickRecorder<R> {
    /// The last tick's record.
    pub fn record(&self) -> &NodeTickRecord {
        &self.record
    }

    /// A tick begins at `now_ns`.
    pub(crate) fn begin(&mut self, now_ns: u64, tick: u64, without_operator: bool) {
        self.record = NodeTickRecord::default();
        self.record.header.capture_ns = now_ns;
        self.record.tick = tick;
        self.record.without_operator = u8::from(without_operator);
        self.record.inputs_complete = 1;
    }

    pub(crate) fn stop_heard(&mut self, heard: Option<bool>) {
        self.record.emergency_stop_heard = match heard {
            None => StopHeard::Nothing,
            Some(false) => StopHeard::Released,
            Some(true) => StopHeard::Engaged,
        }
        .into();
    }

    /// The device read's outcome; readings that do not fit the record are noted as such
    /// ([`DeviceRead::TooLarge`]: a re-run stops there, saying so).
    pub(crate) fn read(&mut self, outcome: Result<Option<&R>, ErrorKind>) {
        let (read, error) = match outcome {
            Ok(Some(readings)) => {
                self.scratch.clear();
                let fits = (self.encode)(readings, &mut self.scratch).is_ok()
                    && self
                        .scratch
                        .iter()
                        .all(|&b| self.record.readings.push(b).is_ok());
                if fits {
                    (DeviceRead::Readings, DeviceErrorCode::None)
                } else {
                    self.record.readings.clear();
                    (DeviceRead::TooLarge, DeviceErrorCode::None)
                }
            }
            Ok(None) => (DeviceRead::Nothing, DeviceErrorCode::None),
            Err(kind) => (DeviceRead::Failed, kind.into()),
        };
        self.record.device_read = read.into();
        self.record.read_error = error.into();
    }

    pub(crate) fn mode_heard(&mut self, mode: &OperatorModeState) {
        self.note(MODE_SLOT, mode);
    }

    /// The messages the node's slots hold for this tick (after the transport filled them).
    pub(crate) fn inputs<I: Inputs>(&mut self, inputs: &mut I) {
        let mut noting = Noting {
            recorder: self,
            slot: 0,
        };
        let Ok(()) = inputs.visit(&mut noting);
    }

    pub(crate) fn write_refused(&mut self, kind: ErrorKind) {
        self.record.write_error = DeviceErrorCode::from(kind).into();
    }

    fn note<T: Payload>(&mut self, slot: u8, message: &T) {
        let header = message.header();
        let input = TickInput {
            msg_seq: header.msg_seq,
            publish_ns: header.publish_ns,
            slot,
            _reserved: [0; 7],
        };
        if self.record.inputs.push(input).is_err() {
            self.record.inputs_complete = 0;
        }
    }
}

/// Notes every fresh sample of a node's slots, numbering the slots in visiting order.
struct Noting<'a, R> {
    recorder: &'a mut TickRecorder<R>,
    slot: u8,
}

impl<R> Noting<'_, R> {
    fn next_slot(&mut self) -> u8 {
        let slot = self.slot;
        self.slot = self.slot.saturating_add(1);
        slot
    }
}

impl<R> InputVisitor for Noting<'_, R> {
    type Error = std::convert::Infallible;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), Self::Error> {
        let index = self.next_slot();
        if let Some(message) = slot.fresh() {
            self.recorder.note(index, message);
        }
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Drain<T>,
    ) -> Result<(), Self::Error> {
        let index = self.next_slot();
        for message in slot.items() {
            self.recorder.note(index, message);
        }
        Ok(())
    }

    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut LatestInPlace<T>,
    ) -> Result<(), Self::Error> {
        let index = self.next_slot();
        if let Some(message) = slot.fresh() {
            self.recorder.note(index, message);
        }
        Ok(())
    }
}
