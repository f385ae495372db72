//! The check's [`Transport`]: one tick's inputs taken from the recording (the frame the live
//! node worked on, the messages it had received by then) and its outputs kept for comparison.

use std::any::Any;

use harvest_ipc::catalogue::{CAMERA_RGBD, LASER_SCAN_RESULT};
use harvest_ipc::payloads::{
    AppleDetections, LaserScanRequest, LaserScanResult, OperatorModeState, RgbdFrame,
};
use harvest_ipc::{Channel, Payload};
use harvest_node::{
    InputVisitor, Inputs, LatestInPlace, Loaned, OutputVisitor, Outputs, Transport,
    ports::{Drain, Latest, Out},
};

use crate::check::held_sample::HeldSample;

/// What perception sent in the ticks re-run so far.
#[derive(Debug, Default)]
pub struct RerunOutputs {
    pub detections: Vec<AppleDetections>,
    pub scan_requests: Vec<LaserScanRequest>,
}

/// One tick of perception on recorded inputs: `frame` is swapped into the node's frame slot
/// (no copy), `scan_results` are the results it drains.
pub struct RecordedInputs<'a> {
    pub frame: &'a mut Box<RgbdFrame>,
    pub scan_results: &'a [LaserScanResult],
    pub sent: &'a mut RerunOutputs,
}

/// The check's transports cannot fail.
#[derive(Debug, thiserror::Error)]
#[error("recorded inputs")]
pub enum NoFailure {}

struct Fill<'b, 'a> {
    inputs: &'b mut RecordedInputs<'a>,
}

impl InputVisitor for Fill<'_, '_> {
    type Error = NoFailure;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), NoFailure> {
        slot.begin();
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Drain<T>,
    ) -> Result<(), NoFailure> {
        slot.begin();
        if channel.spec.topic == LASER_SCAN_RESULT.spec.topic {
            for result in self.inputs.scan_results {
                if let Some(result) = (result as &dyn Any).downcast_ref::<T>() {
                    slot.push(*result);
                }
            }
        }
        Ok(())
    }

    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut LatestInPlace<T>,
    ) -> Result<(), NoFailure> {
        let Some(holder) = slot.holder_mut::<HeldSample<T>>() else {
            return Ok(());
        };
        holder.fresh = false;
        if channel.spec.topic == CAMERA_RGBD.spec.topic
            && let Some(frame) = (&mut *self.inputs.frame as &mut dyn Any).downcast_mut::<Box<T>>()
        {
            std::mem::swap(frame, &mut holder.value);
            holder.fresh = true;
        }
        Ok(())
    }
}

struct Keep<'b> {
    sent: &'b mut RerunOutputs,
}

impl OutputVisitor for Keep<'_> {
    type Error = NoFailure;

    fn output<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Out<T>,
    ) -> Result<(), NoFailure> {
        let sent = &mut *self.sent;
        slot.flush(|value| {
            if let Some(request) = (value as &dyn Any).downcast_ref::<LaserScanRequest>() {
                sent.scan_requests.push(*request);
            }
            Ok(())
        })
    }

    fn loaned<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Loaned<T>,
    ) -> Result<(), NoFailure> {
        if let (true, Some(holder)) = slot.take_send::<HeldSample<T>>()
            && let Some(detections) = (&*holder.value as &dyn Any).downcast_ref::<AppleDetections>()
        {
            self.sent.detections.push(*detections);
        }
        Ok(())
    }
}

impl Transport for RecordedInputs<'_> {
    type Error = NoFailure;

    /// Perception obeys neither the stop nor the mode (a sensor node): none is given.
    fn emergency_stop(&mut self) -> Result<Option<bool>, NoFailure> {
        Ok(None)
    }

    fn operator_mode(&mut self) -> Result<Option<OperatorModeState>, NoFailure> {
        Ok(None)
    }

    fn read_inputs<I: Inputs>(&mut self, inputs: &mut I) -> Result<(), NoFailure> {
        inputs.visit(&mut Fill { inputs: self })
    }

    fn publish<O: Outputs>(&mut self, outputs: &mut O) -> Result<(), NoFailure> {
        outputs.visit(&mut Keep {
            sent: &mut *self.sent,
        })
    }
}
