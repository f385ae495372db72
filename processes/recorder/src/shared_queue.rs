//! The queue from the receiving thread to a helper thread (the mapped view, the camera video,
//! the flight recorder): bounded in messages and in bytes, and never blocking the sender. A
//! message that does not fit is dropped and counted; its shared buffer goes back to its owner.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::time::Duration;

/// A queued message's size as the byte bound counts it.
pub trait Weighed {
    fn bytes(&self) -> usize;
}

/// A queue of at most `max_messages` messages and `max_bytes` bytes.
pub fn bounded<T: Weighed>(
    max_messages: usize,
    max_bytes: usize,
) -> (QueueSender<T>, QueueReceiver<T>) {
    let (sender, receiver) = mpsc::sync_channel(max_messages);
    let pending_bytes = Arc::new(AtomicUsize::new(0));
    (
        QueueSender {
            sender,
            pending_bytes: pending_bytes.clone(),
            max_bytes,
            dropped: 0,
        },
        QueueReceiver {
            receiver,
            pending_bytes,
        },
    )
}

/// The receiving thread's end.
pub struct QueueSender<T> {
    sender: SyncSender<T>,
    pending_bytes: Arc<AtomicUsize>,
    max_bytes: usize,
    dropped: u64,
}

impl<T: Weighed> QueueSender<T> {
    /// True while a message of about `bytes` fits.
    pub fn has_room(&self, bytes: usize) -> bool {
        self.pending_bytes.load(Ordering::Relaxed) + bytes <= self.max_bytes
    }

    /// Queues `message`, or drops and counts it when the queue is full.
    pub fn offer(&mut self, message: T) -> bool {
        let bytes = message.bytes();
        if !self.has_room(bytes) {
            self.dropped += 1;
            return false;
        }
        self.pending_bytes.fetch_add(bytes, Ordering::Relaxed);
        match self.sender.try_send(message) {
            Ok(()) => true,
            Err(TrySendError::Full(message) | TrySendError::Disconnected(message)) => {
                self.pending_bytes
                    .fetch_sub(message.bytes(), Ordering::Relaxed);
                self.dropped += 1;
                false
            }
        }
    }

    /// Messages dropped so far because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// The helper thread's end.
pub struct QueueReceiver<T> {
    receiver: Receiver<T>,
    pending_bytes: Arc<AtomicUsize>,
}

impl<T: Weighed> QueueReceiver<T> {
    /// The next message; `None` once the sender is gone and the queue empty.
    pub fn recv(&self) -> Option<T> {
        self.receiver.recv().ok().map(|message| self.taken(message))
    }

    /// The next message within `timeout`.
    pub fn recv_timeout(&self, timeout: Duration) -> Result<T, RecvTimeoutError> {
        self.receiver
            .recv_timeout(timeout)
            .map(|message| self.taken(message))
    }

    fn taken(&self, message: T) -> T {
        self.pending_bytes
            .fetch_sub(message.bytes(), Ordering::Relaxed);
        message
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Sized(usize);

    impl Weighed for Sized {
        fn bytes(&self) -> usize {
            self.0
        }
    }

    #[test]
    fn drops_past_either_bound_and_frees_room_on_receipt() {
        let (mut sender, receiver) = bounded::<Sized>(2, 100);
        assert!(sender.offer(Sized(60)));
        assert!(!sender.offer(Sized(50)), "over the byte bound");
        assert!(sender.offer(Sized(40)));
        assert!(!sender.offer(Sized(0)), "over the message bound");
        assert_eq!(sender.dropped(), 2);
        assert_eq!(receiver.recv().map(|m| m.0), Some(60));
        assert!(sender.has_room(60));
        drop(sender);
        assert_eq!(receiver.recv().map(|m| m.0), Some(40));
        assert!(receiver.recv().is_none());
    }
}
