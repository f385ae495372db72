//! The in-process backend: nodes exchange messages through an in-memory [`Bus`] and run on a
//! simulated clock in a deterministic order ([`Schedule`]), so an evaluation or a test runs the
//! robot's nodes through the robot's tick ([`crate::tick::Runner`]) without shared memory, as
//! fast as the machine allows, and gets the same result on every run.
//!
//! The bus keeps the last [`KEPT_PER_CHANNEL`] messages of each channel; a reader that falls
//! further behind loses the oldest (as the shared-memory channels' safe overflow does). Each
//! node reads with its own cursors, so a message is seen once per node. Messages are stamped
//! like the transport stamps them: `msg_seq` per channel from 1, `publish_ns` the simulated
//! time.

use std::any::Any;
use std::collections::{HashMap, VecDeque};

use harvest_ipc::catalogue::{Channel, EMERGENCY_STOP, OPERATOR_MODE};
use harvest_ipc::payload::Payload;
use harvest_ipc::payloads::OperatorModeState;

use crate::node::Node;
use crate::ports::{Drain, Latest, Out};
use crate::tick::Runner;
use crate::transport::{InputVisitor, Inputs, OutputVisitor, Outputs, Transport};

/// Messages kept per channel.
pub const KEPT_PER_CHANNEL: usize = 256;

struct Topic<T> {
    /// `msg_seq` of the newest message (0: none yet).
    last_seq: u64,
    recent: VecDeque<T>,
}

/// The channels of one in-process run.
#[derive(Default)]
pub struct Bus {
    topics: HashMap<&'static str, Box<dyn Any>>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("channels", &self.topics.len())
            .finish()
    }
}

impl Bus {
    fn topic<T: Payload + Copy + 'static>(&mut self, channel: Channel<T>) -> &mut Topic<T> {
        let entry = self.topics.entry(channel.spec.topic).or_insert_with(|| {
            Box::new(Topic::<T> {
                last_seq: 0,
                recent: VecDeque::new(),
            })
        });
        // One payload type per topic name (the catalogue declares each once).
        match entry.downcast_mut::<Topic<T>>() {
            Some(topic) => topic,
            None => unreachable!("topic {} used with two payload types", channel.spec.topic),
        }
    }

    /// Sends `value` on `channel` at `now_ns` (stamps `msg_seq` and `publish_ns`); returns
    /// its `msg_seq`.
    pub fn publish<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        mut value: T,
        now_ns: u64,
    ) -> u64 {
        let topic = self.topic(channel);
        topic.last_seq += 1;
        let header = value.header_mut();
        header.msg_seq = topic.last_seq;
        header.publish_ns = now_ns;
        if topic.recent.len() == KEPT_PER_CHANNEL {
            topic.recent.pop_front();
        }
        topic.recent.push_back(value);
        topic.last_seq
    }

    /// The newest message on `channel`, if any.
    pub fn latest<T: Payload + Copy + 'static>(&mut self, channel: Channel<T>) -> Option<T> {
        self.topic(channel).recent.back().copied()
    }

    /// Hands every message after `*cursor` to `each`, oldest first, and moves the cursor (a
    /// reader's own position on the channel; 0: from the oldest kept).
    pub fn read_since<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        cursor: &mut u64,
        mut each: impl FnMut(T),
    ) {
        let topic = self.topic(channel);
        let first_kept = topic.last_seq + 1 - topic.recent.len() as u64;
        let skip = cursor.saturating_add(1).saturating_sub(first_kept) as usize;
        for value in topic.recent.iter().skip(skip) {
            each(*value);
        }
        *cursor = topic.last_seq;
    }
}

/// One node's read positions on the bus.
#[derive(Debug, Default, Clone)]
pub struct Cursors {
    inputs: Vec<u64>,
    emergency_stop: u64,
    operator_mode: u64,
}

/// The [`Transport`] of one node on a [`Bus`] at one simulated time.
pub struct InProcess<'a> {
    pub bus: &'a mut Bus,
    pub cursors: &'a mut Cursors,
    pub now_ns: u64,
}

impl std::fmt::Debug for InProcess<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InProcess")
            .field("now_ns", &self.now_ns)
            .finish()
    }
}

/// The in-process backend cannot fail.
#[derive(Debug, thiserror::Error)]
#[error("in-process transport")]
pub enum Never {}

struct Fill<'b> {
    bus: &'b mut Bus,
    cursors: &'b mut Vec<u64>,
    index: usize,
}

impl Fill<'_> {
    fn cursor(&mut self) -> &mut u64 {
        if self.cursors.len() <= self.index {
            self.cursors.resize(self.index + 1, 0);
        }
        let index = self.index;
        self.index += 1;
        &mut self.cursors[index]
    }
}

impl InputVisitor for Fill<'_> {
    type Error = Never;

    fn latest<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Latest<T>,
    ) -> Result<(), Never> {
        slot.begin();
        let mut cursor = *self.cursor();
        let mut newest = None;
        self.bus
            .read_since(channel, &mut cursor, |value| newest = Some(value));
        self.cursors[self.index - 1] = cursor;
        if let Some(value) = newest {
            slot.set(value);
        }
        Ok(())
    }

    fn drain<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Drain<T>,
    ) -> Result<(), Never> {
        slot.begin();
        let mut cursor = *self.cursor();
        self.bus
            .read_since(channel, &mut cursor, |value| slot.push(value));
        self.cursors[self.index - 1] = cursor;
        Ok(())
    }
}

struct Send<'b> {
    bus: &'b mut Bus,
    now_ns: u64,
}

impl OutputVisitor for Send<'_> {
    type Error = Never;

    fn output<T: Payload + Copy + 'static>(
        &mut self,
        channel: Channel<T>,
        slot: &mut Out<T>,
    ) -> Result<(), Never> {
        let (bus, now_ns) = (&mut *self.bus, self.now_ns);
        slot.flush(|value| {
            bus.publish(channel, *value, now_ns);
            Ok(())
        })
    }
}

impl Transport for InProcess<'_> {
    type Error = Never;

    fn emergency_stop(&mut self) -> Result<Option<bool>, Never> {
        let mut newest = None;
        self.bus
            .read_since(EMERGENCY_STOP, &mut self.cursors.emergency_stop, |stop| {
                newest = Some(stop.engaged != 0)
            });
        Ok(newest)
    }

    fn operator_mode(&mut self) -> Result<Option<OperatorModeState>, Never> {
        let mut newest = None;
        self.bus
            .read_since(OPERATOR_MODE, &mut self.cursors.operator_mode, |mode| {
                newest = Some(mode)
            });
        Ok(newest)
    }

    fn read_inputs<I: Inputs>(&mut self, inputs: &mut I) -> Result<(), Never> {
        inputs.visit(&mut Fill {
            bus: self.bus,
            cursors: &mut self.cursors.inputs,
            index: 0,
        })
    }

    fn publish<O: Outputs>(&mut self, outputs: &mut O) -> Result<(), Never> {
        outputs.visit(&mut Send {
            bus: self.bus,
            now_ns: self.now_ns,
        })
    }
}

/// A node of a [`Schedule`] ended the run.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct ScheduleError {
    pub message: String,
}

trait Scheduled: Any {
    fn tick(&mut self, transport: &mut InProcess<'_>, now_ns: u64) -> Result<(), ScheduleError>;
    fn shutdown(&mut self, transport: &mut InProcess<'_>, now_ns: u64);
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<N: Node + 'static> Scheduled for Runner<N> {
    fn tick(&mut self, transport: &mut InProcess<'_>, now_ns: u64) -> Result<(), ScheduleError> {
        Runner::tick(self, transport, now_ns).map_err(|error| ScheduleError {
            message: error.to_string(),
        })
    }

    fn shutdown(&mut self, transport: &mut InProcess<'_>, now_ns: u64) {
        let Ok(()) = Runner::shutdown(self, transport, now_ns);
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

struct Entry {
    runner: Box<dyn Scheduled>,
    period_ns: u64,
    next_ns: u64,
    cursors: Cursors,
}

/// Which node of a [`Schedule`] (in the order they were added).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeHandle(usize);

/// Nodes on a simulated clock: each runs every `period_ns` from its first tick; at equal times
/// the node added first runs first. Between runs the caller may publish on the bus (what the
/// evaluation's world and devices produce) and look at the nodes.
#[derive(Default)]
pub struct Schedule {
    now_ns: u64,
    bus: Bus,
    entries: Vec<Entry>,
}

impl std::fmt::Debug for Schedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Schedule")
            .field("now_ns", &self.now_ns)
            .field("nodes", &self.entries.len())
            .finish()
    }
}

impl Schedule {
    /// An empty schedule at simulated time `start_ns`.
    pub fn new(start_ns: u64) -> Self {
        Self {
            now_ns: start_ns,
            ..Self::default()
        }
    }

    /// Adds a node that ticks every `period_ns` (> 0), the first time at `first_ns`.
    pub fn add<N: Node + 'static>(
        &mut self,
        runner: Runner<N>,
        period_ns: u64,
        first_ns: u64,
    ) -> NodeHandle {
        self.entries.push(Entry {
            runner: Box::new(runner),
            period_ns: period_ns.max(1),
            next_ns: first_ns,
            cursors: Cursors::default(),
        });
        NodeHandle(self.entries.len() - 1)
    }

    /// The simulated time: the last tick run, or the end of the last [`Self::run_until`].
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    pub fn bus_mut(&mut self) -> &mut Bus {
        &mut self.bus
    }

    /// The runner of `handle` if its node is an `N`.
    pub fn runner<N: Node + 'static>(&self, handle: NodeHandle) -> Option<&Runner<N>> {
        self.entries
            .get(handle.0)
            .and_then(|entry| entry.runner.as_any().downcast_ref())
    }

    pub fn runner_mut<N: Node + 'static>(&mut self, handle: NodeHandle) -> Option<&mut Runner<N>> {
        self.entries
            .get_mut(handle.0)
            .and_then(|entry| entry.runner.as_any_mut().downcast_mut())
    }

    /// Runs every tick due up to and including `end_ns`, in time order (ties: the node added
    /// first), then sets the clock to `end_ns`.
    pub fn run_until(&mut self, end_ns: u64) -> Result<(), ScheduleError> {
        loop {
            let due = self
                .entries
                .iter()
                .enumerate()
                .filter(|(_, entry)| entry.next_ns <= end_ns)
                .min_by_key(|(index, entry)| (entry.next_ns, *index))
                .map(|(index, _)| index);
            let Some(index) = due else {
                break;
            };
            let entry = &mut self.entries[index];
            let now_ns = entry.next_ns;
            self.now_ns = now_ns;
            entry.next_ns = now_ns + entry.period_ns;
            let mut transport = InProcess {
                bus: &mut self.bus,
                cursors: &mut entry.cursors,
                now_ns,
            };
            entry.runner.tick(&mut transport, now_ns)?;
        }
        self.now_ns = self.now_ns.max(end_ns);
        Ok(())
    }

    /// Ends the run: every node's devices in their safe state and its last messages.
    pub fn shutdown(&mut self) {
        let now_ns = self.now_ns;
        for entry in &mut self.entries {
            let mut transport = InProcess {
                bus: &mut self.bus,
                cursors: &mut entry.cursors,
                now_ns,
            };
            entry.runner.shutdown(&mut transport, now_ns);
        }
    }
}
