//! How a node reads a channel and writes one: the slots of its input and output structs.
//!
//! A transport fills the input slots before each step (in the order the node visits them) and
//! empties the output slots after it. Per-tick work allocates nothing once the buffers have
//! grown to the largest burst seen.

/// The newest sample heard on a channel (kept across ticks until a newer one arrives).
#[derive(Debug, Clone)]
pub struct Latest<T> {
    value: Option<T>,
    fresh: bool,
}

impl<T> Default for Latest<T> {
    fn default() -> Self {
        Self {
            value: None,
            fresh: false,
        }
    }
}

impl<T> Latest<T> {
    /// The newest sample heard so far, if any.
    pub fn get(&self) -> Option<&T> {
        self.value.as_ref()
    }

    /// The newest sample if it arrived since the previous tick.
    pub fn fresh(&self) -> Option<&T> {
        if self.fresh {
            self.value.as_ref()
        } else {
            None
        }
    }

    /// Transport side: a tick begins (nothing fresh yet).
    pub fn begin(&mut self) {
        self.fresh = false;
    }

    /// Transport side: a newer sample arrived.
    pub fn set(&mut self, value: T) {
        self.value = Some(value);
        self.fresh = true;
    }
}

/// Every sample that arrived on a channel since the previous tick, oldest first.
#[derive(Debug, Clone)]
pub struct Drain<T> {
    items: Vec<T>,
}

impl<T> Default for Drain<T> {
    fn default() -> Self {
        Self { items: Vec::new() }
    }
}

impl<T> Drain<T> {
    /// The samples of this tick, oldest first.
    pub fn items(&self) -> &[T] {
        &self.items
    }

    /// Transport side: a tick begins.
    pub fn begin(&mut self) {
        self.items.clear();
    }

    /// Transport side: one more sample.
    pub fn push(&mut self, value: T) {
        self.items.push(value);
    }
}

/// The messages a node sends on a channel in one tick, in order.
#[derive(Debug, Clone)]
pub struct Out<T> {
    pending: Vec<T>,
}

impl<T> Default for Out<T> {
    fn default() -> Self {
        Self {
            pending: Vec::new(),
        }
    }
}

impl<T> Out<T> {
    /// Queues a message (the transport stamps `msg_seq` and `publish_ns`; the node sets
    /// `capture_ns`).
    pub fn send(&mut self, value: T) {
        self.pending.push(value);
    }

    /// The messages queued this tick.
    pub fn pending(&self) -> &[T] {
        &self.pending
    }

    /// Transport side: hands every queued message to `send`, oldest first, and empties the
    /// slot (also when `send` fails, so a failed tick does not repeat its messages).
    pub fn flush<E>(&mut self, mut send: impl FnMut(&T) -> Result<(), E>) -> Result<(), E> {
        let result = self.pending.iter().try_for_each(&mut send);
        self.pending.clear();
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latest_keeps_the_value_and_says_when_it_is_fresh() {
        let mut slot = Latest::default();
        assert_eq!(slot.get(), None);
        slot.begin();
        slot.set(3);
        assert_eq!((slot.get(), slot.fresh()), (Some(&3), Some(&3)));
        slot.begin();
        assert_eq!((slot.get(), slot.fresh()), (Some(&3), None));
    }

    #[test]
    fn drain_holds_one_tick_and_out_flushes_in_order() {
        let mut drain = Drain::default();
        drain.push(1);
        drain.push(2);
        assert_eq!(drain.items(), [1, 2]);
        drain.begin();
        assert!(drain.items().is_empty());
        let mut out = Out::default();
        out.send('a');
        out.send('b');
        let mut sent = Vec::new();
        out.flush(|m| {
            sent.push(*m);
            Ok::<(), ()>(())
        })
        .ok();
        assert_eq!(sent, ['a', 'b']);
        assert!(out.pending().is_empty());
    }
}
