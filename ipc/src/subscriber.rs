//! Typed subscriber: received samples are read in place in shared memory; sequence gaps are
//! counted as drops.
//!
//! After a wake-up, a loop must take *every* pending sample: the wake-up events are consumed
//! with the first take, so a sample left behind waits for the next publication. The
//! [`Subscriber::drain`] family does this by construction (all pending samples, and the pending
//! wake-ups, whatever the handler does); [`Subscriber::receive_latest`] keeps only the newest.
//! [`Subscriber::receive`] takes one sample and leaves the loop to the caller.

use crate::catalogue::Channel;
use crate::context::Ipc;
use crate::error::ReceiveError;
use crate::payload::Payload;
use iceoryx2::port::listener::Listener;
use iceoryx2::sample::Sample;
use std::cell::{Cell, RefCell};
use std::ops::Deref;

/// A subscriber on one catalogue channel, with the listener a wait set attaches to.
pub struct Subscriber<T: Payload> {
    channel: Channel<T>,
    port: iceoryx2::port::subscriber::Subscriber<Ipc, T, ()>,
    listener: Listener<Ipc>,
    last_seq_by_publisher: RefCell<Vec<(u128, u64)>>,
    received: Cell<u64>,
    dropped: Cell<u64>,
    batch_done: Cell<bool>,
}

/// A received sample, borrowed from shared memory until dropped.
pub struct Received<T: Payload> {
    sample: Sample<Ipc, T, ()>,
}

impl<T: Payload> Deref for Received<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.sample.payload()
    }
}

impl<T: Payload> Subscriber<T> {
    pub(crate) fn new(
        channel: Channel<T>,
        port: iceoryx2::port::subscriber::Subscriber<Ipc, T, ()>,
        listener: Listener<Ipc>,
    ) -> Self {
        Self {
            channel,
            port,
            listener,
            last_seq_by_publisher: RefCell::new(Vec::new()),
            received: Cell::new(0),
            dropped: Cell::new(0),
            batch_done: Cell::new(true),
        }
    }

    /// The channel this subscriber reads.
    pub fn channel(&self) -> Channel<T> {
        self.channel
    }

    /// Attach this to a wait set: it fires when a publisher sent on the channel.
    pub fn listener(&self) -> &Listener<Ipc> {
        &self.listener
    }

    /// Takes the next sample, if any. The first call after a wake also consumes the pending
    /// wake-up events (before looking at the queue, so no wake-up is lost): after each wake,
    /// call it until it returns `None`, or use [`Self::drain`], which cannot stop early.
    pub fn receive(&self) -> Result<Option<Received<T>>, ReceiveError> {
        if self.batch_done.replace(false) {
            self.drain_events();
        }
        let sample = self.take()?;
        if sample.is_none() {
            self.batch_done.set(true);
        }
        Ok(sample)
    }

    /// Takes the next sample, if any, for a caller that spins on the queue instead of waiting
    /// on [`Self::listener`] (busy-poll). The wake-up events are consumed on the first empty
    /// poll after a sample arrived, so a spinning caller makes no system call per empty poll
    /// and none between a sample's arrival and its return. Do not mix with a wait set.
    pub fn poll(&self) -> Result<Option<Received<T>>, ReceiveError> {
        let sample = self.take()?;
        if sample.is_some() {
            self.batch_done.set(true);
        } else if self.batch_done.replace(false) {
            self.drain_events();
        }
        Ok(sample)
    }

    /// Events only mean "look at the queue": drain them so the wait set sleeps again.
    fn drain_events(&self) {
        if let Err(error) = self.listener.try_wait(|_| {}) {
            tracing::debug!(
                topic = self.channel.spec.topic,
                ?error,
                "draining events failed"
            );
        }
    }

    fn take(&self) -> Result<Option<Received<T>>, ReceiveError> {
        let sample = self.port.receive().map_err(|error| ReceiveError {
            topic: self.channel.spec.topic,
            reason: format!("{error:?}"),
        })?;
        Ok(sample.map(|sample| {
            self.count(sample.origin().value(), sample.payload().header().msg_seq);
            Received { sample }
        }))
    }

    /// Hands every pending sample, oldest first, to `on_sample`, after consuming the pending
    /// wake-up events; returns how many it handed. Nothing is left queued when it returns `Ok`.
    pub fn drain(&self, mut on_sample: impl FnMut(&T)) -> Result<usize, ReceiveError> {
        self.try_drain(|sample| {
            on_sample(sample);
            Ok::<(), ReceiveError>(())
        })
    }

    /// [`Self::drain`] with a handler that can fail. After the first failure the remaining
    /// pending samples are still taken, and dropped unhandled (counted as received), so the
    /// queue is empty either way; the first error is returned. A receive error stops the drain
    /// (iceoryx2 could not hand out a sample) and is returned as `E`.
    pub fn try_drain<E: From<ReceiveError>>(
        &self,
        mut on_sample: impl FnMut(&T) -> Result<(), E>,
    ) -> Result<usize, E> {
        self.drain_events();
        self.batch_done.set(true);
        let mut handed = 0;
        let mut failure = None;
        while let Some(sample) = self.take()? {
            if failure.is_none() {
                handed += 1;
                if let Err(error) = on_sample(&sample) {
                    failure = Some(error);
                }
            }
        }
        match failure {
            Some(error) => Err(error),
            None => Ok(handed),
        }
    }

    /// Takes every queued sample and returns only the newest (for state-like channels).
    pub fn receive_latest(&self) -> Result<Option<Received<T>>, ReceiveError> {
        let mut latest = None;
        while let Some(sample) = self.receive()? {
            latest = Some(sample);
        }
        Ok(latest)
    }

    /// Messages received so far.
    pub fn received_count(&self) -> u64 {
        self.received.get()
    }

    /// Messages lost so far, from gaps in each publisher's `msg_seq`.
    pub fn dropped_count(&self) -> u64 {
        self.dropped.get()
    }

    fn count(&self, publisher_id: u128, msg_seq: u64) {
        self.received.set(self.received.get() + 1);
        let mut last_seqs = self.last_seq_by_publisher.borrow_mut();
        match last_seqs.iter_mut().find(|(id, _)| *id == publisher_id) {
            Some((_, last)) => {
                if msg_seq > *last + 1 {
                    self.dropped.set(self.dropped.get() + (msg_seq - *last - 1));
                }
                *last = msg_seq.max(*last);
            }
            None => last_seqs.push((publisher_id, msg_seq)),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::catalogue::{Channel, Qos};
    use crate::payloads::EmergencyStop;
    use crate::{Context, Payload, ScratchDomain};

    fn pending_events(listener: &iceoryx2::port::listener::Listener<crate::Ipc>) -> usize {
        let mut count = 0;
        listener.try_wait(|_| count += 1).expect("try_wait");
        count
    }

    fn publish_engaged(publisher: &mut crate::Publisher<EmergencyStop>, values: &[u8]) {
        for &engaged in values {
            publisher
                .publish_with(1, |message: &mut EmergencyStop| message.engaged = engaged)
                .expect("publish");
        }
    }

    #[test]
    fn drain_hands_every_sample_and_consumes_the_wake_ups() {
        let domain = ScratchDomain::new("drain");
        let context = Context::new(&domain, "drain-test").expect("context");
        let channel = Channel::<EmergencyStop>::ad_hoc("test/drain", Qos::SMALL);
        let subscriber = context.subscriber(channel).expect("subscriber");
        let mut publisher = context.publisher(channel).expect("publisher");
        publish_engaged(&mut publisher, &[1, 0, 1]);
        let mut seen = Vec::new();
        let handed = subscriber
            .drain(|message| seen.push((message.engaged, message.header().msg_seq)))
            .expect("drain");
        assert_eq!(handed, 3);
        assert_eq!(seen, vec![(1, 1), (0, 2), (1, 3)]);
        assert_eq!(pending_events(subscriber.listener()), 0);
        assert!(subscriber.receive().expect("receive").is_none());
    }

    #[test]
    fn a_failing_handler_still_leaves_nothing_queued() {
        let domain = ScratchDomain::new("trydrain");
        let context = Context::new(&domain, "try-drain-test").expect("context");
        let channel = Channel::<EmergencyStop>::ad_hoc("test/try_drain", Qos::SMALL);
        let subscriber = context.subscriber(channel).expect("subscriber");
        let mut publisher = context.publisher(channel).expect("publisher");
        publish_engaged(&mut publisher, &[1, 2, 3, 4]);
        let mut handled = Vec::new();
        let result = subscriber.try_drain(|message| {
            handled.push(message.engaged);
            if message.engaged == 2 {
                return Err(crate::error::ReceiveError {
                    topic: "test/try_drain",
                    reason: "handler refused 2".to_owned(),
                });
            }
            Ok(())
        });
        let error = result.expect_err("the handler failed");
        assert_eq!(error.reason, "handler refused 2");
        assert_eq!(handled, vec![1, 2]);
        assert_eq!(subscriber.received_count(), 4);
        assert_eq!(pending_events(subscriber.listener()), 0);
        assert!(subscriber.receive().expect("receive").is_none());
    }

    #[test]
    fn poll_takes_every_sample_and_drains_the_wake_ups_once_idle() {
        let domain = ScratchDomain::new("poll");
        let context = Context::new(&domain, "poll-test").expect("context");
        let channel = Channel::<EmergencyStop>::ad_hoc("test/poll", Qos::SMALL);
        let subscriber = context.subscriber(channel).expect("subscriber");
        let mut publisher = context.publisher(channel).expect("publisher");
        // The first empty poll consumes whatever was pending before anything was sent.
        assert!(subscriber.poll().expect("poll").is_none());
        publish_engaged(&mut publisher, &[1, 0, 1]);
        let mut seen = Vec::new();
        while let Some(sample) = subscriber.poll().expect("poll") {
            seen.push((sample.engaged, sample.header().msg_seq));
        }
        assert_eq!(seen, vec![(1, 1), (0, 2), (1, 3)]);
        assert_eq!(subscriber.dropped_count(), 0);
        // The empty poll that ended the batch drained the three notifications.
        assert_eq!(pending_events(subscriber.listener()), 0);
        // Nothing new: further empty polls make no system call and find nothing.
        assert!(subscriber.poll().expect("poll").is_none());
    }
}
