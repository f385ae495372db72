//! The check's in-place slots: a frame or a detection set on the heap, allocated once per slot,
//! lent to the node as the shared-memory transport lends its samples.

use std::any::Any;

use harvest_ipc::{Channel, Payload};
use harvest_node::{
    InputVisitor, LatestInPlace, Loaned, OutputVisitor, SampleHolder,
    ports::{Drain, Latest, Out},
};
use harvest_recording::payload_codec::zeroed_box;

/// One sample on the heap; `fresh` while the tick's input holds a new one.
pub struct HeldSample<T> {
    pub value: Box<T>,
    pub fresh: bool,
}

impl<T: 'static> SampleHolder<T> for HeldSample<T> {
    fn sample(&self) -> Option<&T> {
        self.fresh.then_some(&*self.value)
    }

    fn sample_mut(&mut self) -> Option<&mut T> {
        Some(&mut self.value)
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// Gives every in-place slot of a node its [`HeldSample`] (once, before the first tick).
pub struct AttachHeld;

impl InputVisitor for AttachHeld {
    type Error = std::convert::Infallible;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        _slot: &mut Latest<T>,
    ) -> Result<(), Self::Error> {
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        _slot: &mut Drain<T>,
    ) -> Result<(), Self::Error> {
        Ok(())
    }

    fn latest_in_place<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut LatestInPlace<T>,
    ) -> Result<(), Self::Error> {
        slot.attach(Box::new(HeldSample {
            value: zeroed_box::<T>(),
            fresh: false,
        }));
        Ok(())
    }
}

impl OutputVisitor for AttachHeld {
    type Error = std::convert::Infallible;

    fn output<T: Payload + Copy + 'static>(
        &mut self,
        _channel: Channel<T>,
        _slot: &mut Out<T>,
    ) -> Result<(), Self::Error> {
        Ok(())
    }

    fn loaned<T: Payload + 'static>(
        &mut self,
        _channel: Channel<T>,
        slot: &mut Loaned<T>,
    ) -> Result<(), Self::Error> {
        slot.attach(Box::new(HeldSample {
            value: zeroed_box::<T>(),
            fresh: false,
        }));
        Ok(())
    }
}
