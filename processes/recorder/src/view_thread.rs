//! The recording's mapped channels: besides the raw channels (bincode, what replay, the monitor
//! and the `rec` tools read), the recorder writes the stack's channels mapped to Foxglove's
//! schemas (protobuf, `harvest-foxglove-mapping`) at the viewing rates, so a recording opens in
//! Foxglove or Lichtblick as it is.
//!
//! The receiving thread offers each encoded message of a mapped channel ([`ViewFeed::offer`]);
//! what the channel's viewing rate admits goes to this thread over a bounded queue (bounded in
//! bytes too: at most two camera frames) as a shared handle on the writer's buffer, not a copy
//! ([`MessageBytes`]), decoded, mapped (the camera image downscaled and
//! JPEG-encoded) and queued for the writer like any message. When this thread falls behind, its
//! input is dropped and counted: the raw channels never wait for the view. Mapped messages are
//! queued with the raw message's log time on the stack clock (the writer shifts every log time
//! by the session's offset) and carry their stamps on the session's wall-clock time base, so
//! both share one timeline.

use crate::shared_queue::{self, QueueReceiver, QueueSender, Weighed};
use crate::writer_thread::{Enqueuer, MessageBytes, QueuedMessage};
use harvest_foxglove_mapping::encoded::is_mapped;
use harvest_foxglove_mapping::topics::{self, MappedSink, Topic, TopicDescription, encode_into};
use harvest_foxglove_mapping::{
    EncodedMapper, ImageSettings, Mounting, RateLimit, TimeBase, ViewingRates,
};
use harvest_recording::schema::TopicInfo;
use harvest_recording::segment_writer::ForeignChannel;
use harvest_recording::wall_clock::ClockPair;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::thread::JoinHandle;

/// Encoded input bytes that may wait for the view thread (two 6.8 MB frames).
const MAX_PENDING_BYTES: usize = 16 << 20;
/// Input messages that may wait.
const MAX_PENDING_MESSAGES: usize = 256;

/// The mapped topics as the recording's foreign channels.
pub fn foreign_channels() -> Vec<ForeignChannel> {
    topics::all().iter().map(foreign_channel).collect()
}

fn foreign_channel(topic: &TopicDescription) -> ForeignChannel {
    let (schema_name, schema_encoding, schema_data) = match &topic.schema {
        Some(schema) => (
            schema.name.clone(),
            schema.encoding.clone(),
            schema.data.to_vec(),
        ),
        None => (String::new(), String::new(), Vec::new()),
    };
    ForeignChannel {
        topic: topic.name.to_owned(),
        schema_name,
        schema_encoding,
        schema_data,
        message_encoding: topic.message_encoding.clone(),
        metadata: BTreeMap::from([
            ("description".to_owned(), topic.description.to_owned()),
            ("mapping".to_owned(), "harvest-foxglove-mapping".to_owned()),
        ]),
    }
}

struct ViewInput {
    topic: &'static str,
    log_time_ns: u64,
    data: MessageBytes,
}

impl Weighed for ViewInput {
    fn bytes(&self) -> usize {
        self.data.len()
    }
}

/// What the view thread did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ViewReport {
    /// Raw messages offered and admitted by the viewing rates.
    pub admitted: u64,
    /// Admitted messages dropped because the view thread was behind.
    pub dropped_behind: u64,
    /// Mapped messages queued for the writer.
    pub written: u64,
    /// Mapped messages the writer queue had no room for.
    pub dropped_by_queue: u64,
    /// Raw messages that did not decode or map.
    pub failed: u64,
}

/// The receiving side's handle on the view thread.
pub struct ViewFeed {
    inputs: QueueSender<ViewInput>,
    /// Topic index -> the channel's viewing-rate limit (mapped channels only).
    limits: BTreeMap<usize, RateLimit>,
    admitted: u64,
    thread: JoinHandle<ViewReport>,
}

impl ViewFeed {
    /// Starts the view thread for the recording's `topics` (catalogue indices) whose mapped
    /// channels follow at `first_index` in the writer's table.
    pub fn spawn(
        topics: &[TopicInfo],
        first_index: usize,
        mounting: Mounting,
        enqueuer: Enqueuer,
        session_clock: ClockPair,
    ) -> std::io::Result<Self> {
        let time = TimeBase::realtime(session_clock.monotonic_ns, session_clock.realtime_ns);
        let rates = ViewingRates::VIEWING;
        let limits = topics
            .iter()
            .enumerate()
            .filter(|(_, topic)| is_mapped(topic.spec.topic))
            .map(|(index, topic)| (index, RateLimit::new(rates.min_interval(topic.spec.topic))))
            .collect();
        let positions = topics::all()
            .iter()
            .enumerate()
            .map(|(position, topic)| (topic.name, first_index + position))
            .collect();
        let (inputs, receiver) = shared_queue::bounded(MAX_PENDING_MESSAGES, MAX_PENDING_BYTES);
        let sink = RecordingSink {
            enqueuer,
            positions,
            sequences: BTreeMap::new(),
            report: ViewReport::default(),
            buffer: Vec::new(),
            input_log_time_ns: 0,
        };
        let thread = std::thread::Builder::new()
            .name("recorder-view".to_owned())
            .spawn(move || run(receiver, mounting, time, sink))?;
        Ok(Self {
            inputs,
            limits,
            admitted: 0,
            thread,
        })
    }

    /// Offers one encoded message of the catalogue topic `index`: shared with the view thread
    /// when the topic is mapped, its viewing rate admits it and the thread keeps up.
    pub fn offer(
        &mut self,
        index: usize,
        topic: &'static str,
        log_time_ns: u64,
        data: &MessageBytes,
    ) {
        let Some(limit) = self.limits.get_mut(&index) else {
            return;
        };
        if !limit.admit(log_time_ns) {
            return;
        }
        self.admitted += 1;
        self.inputs.offer(ViewInput {
            topic,
            log_time_ns,
            data: Arc::clone(data),
        });
    }

    /// Maps what is still queued and stops the thread.
    pub fn finish(self) -> ViewReport {
        let dropped_behind = self.inputs.dropped();
        drop(self.inputs);
        let mut report = self.thread.join().unwrap_or_else(|_| {
            tracing::error!("the recorder's view thread panicked; mapped channels are incomplete");
            ViewReport::default()
        });
        report.admitted = self.admitted;
        report.dropped_behind = dropped_behind;
        report
    }
}

/// Queues mapped messages for the writer.
struct RecordingSink {
    enqueuer: Enqueuer,
    /// Mapped topic name -> index in the writer's table.
    positions: BTreeMap<&'static str, usize>,
    sequences: BTreeMap<usize, u32>,
    report: ViewReport,
    buffer: Vec<u8>,
    /// Stack-clock log time of the raw message being mapped: the log time of what it maps to
    /// (the mapper's own log times are already on the wall clock).
    input_log_time_ns: u64,
}

impl MappedSink for RecordingSink {
    type Error = std::convert::Infallible;

    fn write<M: foxglove::Encode>(
        &mut self,
        topic: Topic<M>,
        _wall_log_time_ns: u64,
        message: &M,
    ) -> Result<(), Self::Error> {
        let Some(&index) = self.positions.get(topic.name) else {
            return Ok(());
        };
        if let Err(error) = encode_into(message, &mut self.buffer) {
            tracing::warn!(topic = topic.name, %error, "cannot encode a mapped message");
            return Ok(());
        }
        let sequence = self.sequences.entry(index).or_insert(0);
        *sequence = sequence.wrapping_add(1);
        let queued = QueuedMessage {
            topic: index,
            sequence: *sequence,
            log_time_ns: self.input_log_time_ns,
            publish_time_ns: self.input_log_time_ns,
            data: Arc::new(std::mem::take(&mut self.buffer)),
        };
        if self.enqueuer.try_enqueue(queued) {
            self.report.written += 1;
        } else {
            self.report.dropped_by_queue += 1;
        }
        Ok(())
    }
}

fn run(
    inputs: QueueReceiver<ViewInput>,
    mounting: Mounting,
    time: TimeBase,
    mut sink: RecordingSink,
) -> ViewReport {
    let mut mapper = EncodedMapper::new(time, ImageSettings::VIEWING, mounting);
    let mut warned = false;
    while let Some(input) = inputs.recv() {
        sink.input_log_time_ns = input.log_time_ns;
        if let Err(error) = mapper.map(input.topic, &input.data, input.log_time_ns, &mut sink) {
            sink.report.failed += 1;
            if !std::mem::replace(&mut warned, true) {
                tracing::warn!(%error, "cannot map a recorded message for the Foxglove view");
            }
        }
        sink.enqueuer.release(input.data);
    }
    sink.report
}
