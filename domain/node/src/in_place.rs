//! Slots for large messages (camera frames, point clouds), read and written where the
//! transport keeps them: nothing is copied in or out, and nothing big lands on the stack.
//!
//! A transport that has such memory (shared memory on iceoryx2) attaches a [`SampleHolder`]
//! to each slot when it opens its ports: the holder is its own type (a received sample, a
//! loan), allocated once; per tick the transport only fills and empties it. A backend without
//! such memory leaves the slots without a holder: [`LatestInPlace::fresh`] then finds nothing
//! and [`Loaned::sample_mut`] offers nothing to write (the in-process backend does not carry
//! large messages).

use std::any::Any;

/// The transport's handle of one sample in its memory.
pub trait SampleHolder<T>: Any {
    /// The sample held, if any.
    fn sample(&self) -> Option<&T>;
    /// The sample to write in place, if one can be had (a loan may be taken here).
    fn sample_mut(&mut self) -> Option<&mut T>;
    /// Transport side: its own type back.
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

/// The newest sample that arrived on a channel since the previous tick, read in place (held
/// by the transport until the next tick at the latest).
pub struct LatestInPlace<T: 'static> {
    holder: Option<Box<dyn SampleHolder<T>>>,
}

impl<T: 'static> Default for LatestInPlace<T> {
    fn default() -> Self {
        Self { holder: None }
    }
}

impl<T: 'static> std::fmt::Debug for LatestInPlace<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LatestInPlace")
            .field("attached", &self.holder.is_some())
            .field("fresh", &self.fresh().is_some())
            .finish()
    }
}

impl<T: 'static> LatestInPlace<T> {
    /// The newest sample if one arrived since the previous tick.
    pub fn fresh(&self) -> Option<&T> {
        self.holder.as_ref().and_then(|holder| holder.sample())
    }

    /// Transport side: the holder this slot reads through (once, when the ports open).
    pub fn attach(&mut self, holder: Box<dyn SampleHolder<T>>) {
        self.holder = Some(holder);
    }

    /// Transport side: the attached holder as the transport's type.
    pub fn holder_mut<H: 'static>(&mut self) -> Option<&mut H> {
        self.holder
            .as_mut()
            .and_then(|holder| holder.as_any_mut().downcast_mut::<H>())
    }
}

/// One message a node may write in place in a tick: it writes [`Self::sample_mut`] and calls
/// [`Self::send`]; the transport sends it after the step (stamping `msg_seq` and `publish_ns`;
/// the node sets `capture_ns`). A sample written but not sent is offered again next tick as
/// it was left (a device that fills it over several ticks keeps its work).
pub struct Loaned<T: 'static> {
    holder: Option<Box<dyn SampleHolder<T>>>,
    send: bool,
}

impl<T: 'static> Default for Loaned<T> {
    fn default() -> Self {
        Self {
            holder: None,
            send: false,
        }
    }
}

impl<T: 'static> std::fmt::Debug for Loaned<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Loaned")
            .field("attached", &self.holder.is_some())
            .field("send", &self.send)
            .finish()
    }
}

impl<T: 'static> Loaned<T> {
    /// The sample to write in place (`None`: the transport has none to lend this tick; it
    /// reports why).
    pub fn sample_mut(&mut self) -> Option<&mut T> {
        self.holder.as_mut().and_then(|holder| holder.sample_mut())
    }

    /// Marks the sample written: it is sent after the step.
    pub fn send(&mut self) {
        self.send = true;
    }

    /// Whether [`Self::send`] was called this tick.
    pub fn sending(&self) -> bool {
        self.send
    }

    /// Transport side: the holder this slot writes through (once, when the ports open).
    pub fn attach(&mut self, holder: Box<dyn SampleHolder<T>>) {
        self.holder = Some(holder);
    }

    /// Transport side: takes the "send" mark (the slot is clear for the next tick) and the
    /// attached holder as the transport's type.
    pub fn take_send<H: 'static>(&mut self) -> (bool, Option<&mut H>) {
        let send = std::mem::take(&mut self.send);
        let holder = self
            .holder
            .as_mut()
            .and_then(|holder| holder.as_any_mut().downcast_mut::<H>());
        (send, holder)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A holder on the heap, as a transport's would be in its memory.
    struct Boxed {
        value: Option<u32>,
        sent: Vec<u32>,
    }

    impl SampleHolder<u32> for Boxed {
        fn sample(&self) -> Option<&u32> {
            self.value.as_ref()
        }
        fn sample_mut(&mut self) -> Option<&mut u32> {
            Some(self.value.get_or_insert(0))
        }
        fn as_any_mut(&mut self) -> &mut dyn Any {
            self
        }
    }

    #[test]
    fn without_a_holder_there_is_nothing_to_read_or_write() {
        let input = LatestInPlace::<u32>::default();
        assert_eq!(input.fresh(), None);
        let mut output = Loaned::<u32>::default();
        assert_eq!(output.sample_mut(), None);
    }

    #[test]
    fn a_loaned_sample_is_written_in_place_and_sent_once() {
        let mut output = Loaned::<u32>::default();
        output.attach(Box::new(Boxed {
            value: None,
            sent: Vec::new(),
        }));
        if let Some(sample) = output.sample_mut() {
            *sample = 7;
        }
        output.send();
        let (send, holder) = output.take_send::<Boxed>();
        let holder = holder.expect("the attached holder");
        assert!(send);
        if let Some(value) = holder.value.take() {
            holder.sent.push(value);
        }
        assert_eq!(holder.sent, [7]);
        let (send, _) = output.take_send::<Boxed>();
        assert!(!send, "the mark is taken with the send");
    }

    #[test]
    fn an_input_reads_what_the_transport_put_in_its_holder() {
        let mut input = LatestInPlace::<u32>::default();
        input.attach(Box::new(Boxed {
            value: None,
            sent: Vec::new(),
        }));
        assert_eq!(input.fresh(), None);
        input.holder_mut::<Boxed>().expect("holder").value = Some(3);
        assert_eq!(input.fresh(), Some(&3));
    }
}
