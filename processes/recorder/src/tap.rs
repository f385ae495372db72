//! A tap on one catalogue channel: a subscriber with the channel's largest buffer whose
//! samples are stamped on receipt, encoded with `Payload::encode` (the one copy out of shared
//! memory) and queued for the writer; the view, video and flight threads share that buffer.

use crate::writer_thread::{QueuedMessage, WriterHandle};
use harvest_ipc::error::{OpenChannelError, ReceiveError};
use harvest_ipc::{
    Channel, Context, Ipc, MonotonicClock, Payload, Subscriber, WaitSetGuard, Waiter,
};
use std::cell::Cell;
use std::sync::Arc;

/// Counters of one tapped channel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TapCounts {
    /// Samples taken from the subscriber.
    pub received: u64,
    /// Samples lost before the recorder saw them (gaps in `msg_seq`: the subscriber buffer
    /// overflowed).
    pub dropped_by_transport: u64,
    /// Samples received but not written because the writer queue was full.
    pub dropped_by_queue: u64,
    /// Samples that failed to encode.
    pub encode_failures: u64,
}

/// A type-erased tap, so the recorder holds taps of every payload type in one list.
pub trait Tap {
    /// Index of the channel in the recording's topic table.
    fn topic_index(&self) -> usize;
    fn topic(&self) -> &'static str;
    /// Attaches the subscriber's listener to the wait set.
    fn attach<'a>(&'a self, waiter: &'a Waiter) -> Result<WaitSetGuard<'a, 'a, Ipc>, String>;
    /// Receives every queued sample and hands it to the writer. Returns how many it received.
    fn drain(&self, writer: &mut WriterHandle) -> Result<u64, ReceiveError>;
    fn counts(&self) -> TapCounts;
}

/// The tap of a channel with payload `T`.
pub struct TypedTap<T: Payload> {
    topic_index: usize,
    subscriber: Subscriber<T>,
    dropped_by_queue: Cell<u64>,
    encode_failures: Cell<u64>,
}

impl<T: Payload> TypedTap<T> {
    /// Subscribes to `channel` with the largest buffer its QoS allows.
    pub fn open(
        context: &Context,
        channel: Channel<T>,
        topic_index: usize,
    ) -> Result<Self, OpenChannelError> {
        let subscriber =
            context.subscriber_with_buffer(channel, channel.spec.qos.subscriber_max_buffer_size)?;
        Ok(Self {
            topic_index,
            subscriber,
            dropped_by_queue: Cell::new(0),
            encode_failures: Cell::new(0),
        })
    }
}

impl<T: Payload> Tap for TypedTap<T> {
    fn topic_index(&self) -> usize {
        self.topic_index
    }

    fn topic(&self) -> &'static str {
        self.subscriber.channel().spec.topic
    }

    fn attach<'a>(&'a self, waiter: &'a Waiter) -> Result<WaitSetGuard<'a, 'a, Ipc>, String> {
        waiter
            .waitset()
            .attach_notification(self.subscriber.listener())
            .map_err(|error| format!("{error:?}"))
    }

    fn drain(&self, writer: &mut WriterHandle) -> Result<u64, ReceiveError> {
        let mut received = 0;
        while let Some(sample) = self.subscriber.receive()? {
            let log_time_ns = MonotonicClock::read_ns();
            received += 1;
            let size_hint = std::mem::size_of::<T>();
            // The continuous record (raw, or the camera as video), the mapped view and the
            // flight recorder each take the message or drop it on their own: none waits for
            // another.
            let raw = writer.records_raw(self.topic_index);
            let queue_room = writer.has_room(size_hint);
            let video_due = writer.video_due(self.topic_index, log_time_ns);
            if !queue_room && !video_due && !writer.flight_has_room(size_hint) {
                if raw {
                    self.dropped_by_queue.set(self.dropped_by_queue.get() + 1);
                }
                continue;
            }
            let mut data = writer.take_buffer(size_hint);
            if let Err(error) = sample.encode(&mut data) {
                if self.encode_failures.get() == 0 {
                    tracing::warn!(topic = self.topic(), %error, "cannot encode a sample; skipping it");
                }
                self.encode_failures.set(self.encode_failures.get() + 1);
                writer.give_back(data);
                continue;
            }
            let data = Arc::new(data);
            let header = sample.header();
            let sequence = header.msg_seq as u32;
            writer.offer_flight(
                self.topic_index,
                self.topic(),
                sequence,
                log_time_ns,
                header.publish_ns,
                &data,
            );
            if video_due {
                writer.offer_video(log_time_ns, &data);
            }
            if !queue_room {
                if raw {
                    self.dropped_by_queue.set(self.dropped_by_queue.get() + 1);
                }
                writer.release(data);
                continue;
            }
            writer.offer_view(self.topic_index, self.topic(), log_time_ns, &data);
            if !raw {
                writer.release(data);
                continue;
            }
            let message = QueuedMessage {
                topic: self.topic_index,
                sequence,
                log_time_ns,
                publish_time_ns: header.publish_ns,
                data,
            };
            if !writer.try_enqueue(message) {
                self.dropped_by_queue.set(self.dropped_by_queue.get() + 1);
            }
        }
        Ok(received)
    }

    fn counts(&self) -> TapCounts {
        TapCounts {
            received: self.subscriber.received_count(),
            dropped_by_transport: self.subscriber.dropped_count(),
            dropped_by_queue: self.dropped_by_queue.get(),
            encode_failures: self.encode_failures.get(),
        }
    }
}
