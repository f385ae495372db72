//! Typed publisher: loan shared memory, write in place, stamp the header, send, wake subscribers.

use crate::catalogue::Channel;
use crate::clock::MonotonicClock;
use crate::context::Ipc;
use crate::error::SendError;
use crate::payload::Payload;
use iceoryx2::port::LoanError;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::sample_mut::SampleMut;
use std::ops::{Deref, DerefMut};

/// A publisher on one catalogue channel. Every send is followed by an event on the channel's
/// companion event service, which is what wakes subscribers' wait sets (no polling).
pub struct Publisher<T: Payload> {
    channel: Channel<T>,
    port: iceoryx2::port::publisher::Publisher<Ipc, T, ()>,
    notifier: Notifier<Ipc>,
    last_seq: u64,
}

/// A sample loaned from shared memory; write it in place, then [`Publisher::send`] it.
pub struct Loan<T: Payload> {
    sample: SampleMut<Ipc, T, ()>,
}

impl<T: Payload> Deref for Loan<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.sample.payload()
    }
}

impl<T: Payload> DerefMut for Loan<T> {
    fn deref_mut(&mut self) -> &mut T {
        self.sample.payload_mut()
    }
}

impl<T: Payload> Publisher<T> {
    pub(crate) fn new(
        channel: Channel<T>,
        port: iceoryx2::port::publisher::Publisher<Ipc, T, ()>,
        notifier: Notifier<Ipc>,
    ) -> Self {
        Self {
            channel,
            port,
            notifier,
            last_seq: 0,
        }
    }

    /// The channel this publisher writes.
    pub fn channel(&self) -> Channel<T> {
        self.channel
    }

    /// Sequence number of the last message sent (0 before the first).
    pub fn last_seq(&self) -> u64 {
        self.last_seq
    }

    /// Loans a sample in shared memory. Its bytes are whatever the slot held before (see
    /// [`Payload`]'s safety contract): the caller writes every field it means to send.
    pub fn loan(&self) -> Result<Loan<T>, SendError> {
        let topic = self.channel.spec.topic;
        let uninit = self.port.loan_uninit().map_err(|error| match error {
            LoanError::ExceedsMaxLoans => SendError::LoansExhausted {
                topic,
                max_loans: self.channel.spec.qos.max_loans,
            },
            LoanError::OutOfMemory => SendError::OutOfMemory { topic },
            other => SendError::Loan {
                topic,
                reason: other.to_string(),
            },
        })?;
        // SAFETY: `T: Payload` requires `T: AnyBitPattern` (derived, so checked at compile
        // time): every bit pattern is a valid `T`, and the loaned shared-memory bytes are
        // initialized (kernel zero-fill or an earlier sample).
        let sample = unsafe { uninit.assume_init() };
        Ok(Loan { sample })
    }

    /// Stamps `msg_seq` and `publish_ns`, sends, and notifies subscribers. `capture_ns` must have
    /// been set by the caller. Returns the message's sequence number.
    pub fn send(&mut self, mut loan: Loan<T>) -> Result<u64, SendError> {
        let msg_seq = self.last_seq + 1;
        {
            let header = loan.header_mut();
            header.msg_seq = msg_seq;
            header.publish_ns = MonotonicClock::read_ns();
        }
        loan.sample.send().map_err(|error| SendError::Send {
            topic: self.channel.spec.topic,
            reason: error.to_string(),
        })?;
        self.last_seq = msg_seq;
        // A failed wake-up is not a lost message: subscribers still find it at their next wake.
        if let Err(error) = self.notifier.notify() {
            tracing::debug!(topic = self.channel.spec.topic, ?error, "notify failed");
        }
        Ok(msg_seq)
    }

    /// Loans, lets `write` fill the sample in place, stamps `capture_ns`, and sends.
    pub fn publish_with(
        &mut self,
        capture_ns: u64,
        write: impl FnOnce(&mut T),
    ) -> Result<u64, SendError> {
        let mut loan = self.loan()?;
        write(&mut loan);
        loan.header_mut().capture_ns = capture_ns;
        self.send(loan)
    }

    /// Connects the subscribers that joined since the last send and hands each the channel's
    /// history (on a latched channel, [`Qos::STATE`](crate::catalogue::Qos::STATE), the last
    /// value). iceoryx2 does this at every send only, so a writer that sends on change calls
    /// this between sends, or a late joiner sees nothing until the next change. Cheap when
    /// nobody joined: one read of the service's subscriber-list counter. The history arrives
    /// without an event: the reader finds it at its next read.
    pub fn update_connections(&self) -> Result<(), SendError> {
        self.port
            .update_connections()
            .map_err(|error| SendError::Send {
                topic: self.channel.spec.topic,
                reason: format!("connecting a new subscriber: {error}"),
            })
    }

    /// Sends a small value (copied into the loan). Large payloads use [`Self::publish_with`].
    pub fn publish(&mut self, value: &T) -> Result<u64, SendError>
    where
        T: Copy,
    {
        let mut loan = self.loan()?;
        *loan = *value;
        self.send(loan)
    }
}
