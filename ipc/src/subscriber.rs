//! Typed subscriber: received samples are read in place in shared memory; sequence gaps are
//! counted as drops.

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

    pub fn channel(&self) -> Channel<T> {
        self.channel
    }

    /// Attach this to a wait set: it fires when a publisher sent on the channel.
    pub fn listener(&self) -> &Listener<Ipc> {
        &self.listener
    }

    /// Takes the next sample, if any. The first call after a wake also consumes the pending
    /// wake-up events (before looking at the queue, so no wake-up is lost): after each wake,
    /// call it until it returns `None`.
    pub fn receive(&self) -> Result<Option<Received<T>>, ReceiveError> {
        if self.batch_done.replace(false) {
            // Events only mean "look at the queue": drain them so the wait set sleeps again.
            if let Err(error) = self.listener.try_wait(|_| {}) {
                tracing::debug!(
                    topic = self.channel.spec.topic,
                    ?error,
                    "draining events failed"
                );
            }
        }
        let sample = self.port.receive().map_err(|error| ReceiveError {
            topic: self.channel.spec.topic,
            reason: format!("{error:?}"),
        })?;
        let Some(sample) = sample else {
            self.batch_done.set(true);
            return Ok(None);
        };
        self.count(sample.origin().value(), sample.payload().header().msg_seq);
        Ok(Some(Received { sample }))
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
