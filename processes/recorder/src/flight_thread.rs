//! The flight recorder: every recorded channel at full rate in a bounded RAM ring
//! ([`FlightRing`]), and a clip file of the window around each trigger (a failed attempt, a
//! safety violation, the e-stop engaged, an operator's mark), by default 10 s before and 5 s
//! after it.
//!
//! The receiving thread offers each encoded message ([`FlightFeed::offer`]) as a shared handle
//! on the buffer it encoded into (no copy there); this thread copies it into the ring, hands the
//! buffer back, and looks for triggers in the trigger channels. A trigger opens a clip: the ring's
//! blocks from the window's start go to the clip writer ([`crate::clip_writer`]) at once, each
//! block sealed afterwards follows, and when the window has passed (a message logged after it,
//! or the thread's timer at the window's end: it sleeps on its queue, never polls) the clip is
//! closed. A trigger inside an open window extends it (up to a longest clip) and is listed in the
//! same clip. Each trigger also goes into the continuous record's events channel.
//!
//! Nothing here can stall the receiving thread or the continuous record: the queue to this
//! thread is bounded (messages beyond it are left out of the ring and counted), the ring never
//! waits for the clip writer (a block still being written is not reused: new messages are left
//! out and counted instead), and the clip writer's queue is bounded too.

use crate::clip_writer::{ClipCommand, ClipReport, ClipSettings, ClipWriterHandle};
use crate::shared_queue::{self, QueueReceiver, QueueSender, Weighed};
use crate::writer_thread::{Enqueuer, MessageBytes, QueuedMessage, wall_clock_ns};
use harvest_ipc::MonotonicClock;
use harvest_recording::flight_ring::{FlightRing, RingCounts, RingRecord};
use harvest_recording::recorded_events::{RecordedEvent, TriggerDetector};
use harvest_recording::schema::TopicInfo;
use harvest_recording::wall_clock::{ClockPair, format_utc_compact, format_utc_iso};
use mcap::records::Metadata;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::mpsc::RecvTimeoutError;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The flight recorder's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightSettings {
    /// RAM of the ring, bytes (allocated and made resident once, at start).
    pub ring_bytes: usize,
    /// The ring's block size: the largest message it keeps (plus a small header).
    pub block_bytes: usize,
    /// Window kept before a trigger.
    pub before: Duration,
    /// Window kept after the last trigger of a clip.
    pub after: Duration,
    /// Longest clip: triggers inside an open window extend it up to this.
    pub max_clip: Duration,
    pub clips: ClipSettings,
}

/// Encoded bytes that may wait for this thread (about ten camera frames).
const MAX_PENDING_BYTES: usize = 64 << 20;
/// Messages that may wait.
const MAX_PENDING_MESSAGES: usize = 8192;
/// After a window's end, how long the clip stays open for messages still on their way.
const CLOSE_GRACE: Duration = Duration::from_millis(200);

struct FlightInput {
    topic_index: u32,
    topic: &'static str,
    sequence: u32,
    log_time_ns: u64,
    publish_time_ns: u64,
    data: MessageBytes,
}

impl Weighed for FlightInput {
    fn bytes(&self) -> usize {
        self.data.len()
    }
}

/// What the flight recorder did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlightReport {
    pub ring_capacity_bytes: usize,
    pub ring: RingCounts,
    /// Messages left out of the ring because this thread was behind.
    pub dropped_behind: u64,
    /// Triggers found (marks included).
    pub triggers: u64,
    /// Block batches or events the clip writer had no room for.
    pub clip_commands_dropped: u64,
    pub clips: ClipReport,
}

/// The receiving side's handle on the flight thread.
pub struct FlightFeed {
    inputs: QueueSender<FlightInput>,
    thread: JoinHandle<FlightReport>,
}

/// Where the flight thread's events go in the continuous record.
pub struct LiveEvents {
    pub enqueuer: Enqueuer,
    /// Index of the events channel in the writer's table.
    pub index: usize,
}

impl FlightFeed {
    /// Starts the flight thread (which allocates the ring) and its clip writer.
    #[allow(clippy::too_many_arguments)]
    pub fn spawn(
        settings: FlightSettings,
        topics: Vec<TopicInfo>,
        recording_fields: BTreeMap<String, String>,
        session_records: Vec<Metadata>,
        session_clock: ClockPair,
        log_time_offset_ns: i64,
        live: LiveEvents,
    ) -> std::io::Result<Self> {
        let clips = ClipWriterHandle::spawn(
            settings.clips.clone(),
            topics,
            recording_fields,
            session_records,
            session_clock,
            log_time_offset_ns,
        )?;
        let (inputs, receiver) = shared_queue::bounded(MAX_PENDING_MESSAGES, MAX_PENDING_BYTES);
        // The ring is made on the thread: making 2 GiB resident takes a second or more, and
        // the recorder's taps open meanwhile (the continuous record hears the stack's first
        // messages; the ring misses what comes before it is ready, counted as left out).
        let thread = std::thread::Builder::new()
            .name("recorder-flight".to_owned())
            .spawn(move || {
                let started = std::time::Instant::now();
                let ring = FlightRing::new(settings.ring_bytes, settings.block_bytes);
                tracing::info!(
                    ring_bytes = ring.capacity_bytes(),
                    block_bytes = ring.block_bytes(),
                    resident_after_ms = started.elapsed().as_millis() as u64,
                    before_s = settings.before.as_secs_f64(),
                    after_s = settings.after.as_secs_f64(),
                    clips = %settings.clips.dir.display(),
                    "flight recorder"
                );
                let state = FlightState {
                    report: FlightReport {
                        ring_capacity_bytes: ring.capacity_bytes(),
                        ..FlightReport::default()
                    },
                    settings,
                    ring,
                    detector: TriggerDetector::default(),
                    clips,
                    live,
                    live_sequence: 0,
                    log_time_offset_ns,
                    clip: None,
                };
                state.run(receiver)
            })?;
        Ok(Self { inputs, thread })
    }

    /// True while a message of about `size_bytes` fits in the queue.
    pub fn has_room(&self, size_bytes: usize) -> bool {
        self.inputs.has_room(size_bytes)
    }

    /// Offers one encoded message of catalogue topic `index` (stack-clock times); left out of
    /// the ring (counted) when the thread is behind.
    pub fn offer(
        &mut self,
        index: usize,
        topic: &'static str,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &MessageBytes,
    ) {
        self.inputs.offer(FlightInput {
            topic_index: u32::try_from(index).unwrap_or(u32::MAX),
            topic,
            sequence,
            log_time_ns,
            publish_time_ns,
            data: Arc::clone(data),
        });
    }

    /// Messages left out because the thread was behind (so far).
    pub fn dropped_behind(&self) -> u64 {
        self.inputs.dropped()
    }

    /// Closes an open clip with what it has, waits for the clip writer, stops the thread.
    pub fn finish(self) -> FlightReport {
        let dropped_behind = self.inputs.dropped();
        drop(self.inputs);
        let mut report = self.thread.join().unwrap_or_else(|_| {
            tracing::error!("the recorder's flight thread panicked");
            FlightReport::default()
        });
        report.dropped_behind += dropped_behind;
        report
    }
}

/// The clip being filled.
struct OpenClip {
    end_ns: u64,
    /// Longest end triggers may extend the window to.
    end_limit_ns: u64,
    name: String,
    /// Blocks sealed up to this seal number have been handed to the clip writer.
    sent_seal: u64,
    left_out_at_open: u64,
}

struct FlightState {
    settings: FlightSettings,
    ring: FlightRing,
    detector: TriggerDetector,
    clips: ClipWriterHandle,
    live: LiveEvents,
    live_sequence: u32,
    log_time_offset_ns: i64,
    clip: Option<OpenClip>,
    report: FlightReport,
}

impl FlightState {
    fn run(mut self, inputs: QueueReceiver<FlightInput>) -> FlightReport {
        loop {
            let received = match self.clip.as_ref() {
                None => inputs.recv().ok_or(RecvTimeoutError::Disconnected),
                Some(clip) => {
                    let due_ns = clip.end_ns.saturating_add(CLOSE_GRACE.as_nanos() as u64);
                    let now_ns = MonotonicClock::read_ns();
                    if now_ns >= due_ns {
                        self.close_clip();
                        continue;
                    }
                    inputs.recv_timeout(Duration::from_nanos(due_ns - now_ns))
                }
            };
            match received {
                Ok(input) => self.on_message(input),
                Err(RecvTimeoutError::Timeout) => self.close_clip(),
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        self.close_clip();
        self.report.ring = self.ring.counts();
        let FlightState {
            clips, mut report, ..
        } = self;
        report.clips = clips.finish();
        report
    }

    fn utc(&self, stack_ns: u64) -> String {
        format_utc_iso(wall_clock_ns(stack_ns, self.log_time_offset_ns))
    }

    fn on_message(&mut self, input: FlightInput) {
        if self
            .clip
            .as_ref()
            .is_some_and(|clip| input.log_time_ns > clip.end_ns)
        {
            self.close_clip();
        }
        self.ring.append(&RingRecord {
            topic: input.topic_index,
            sequence: input.sequence,
            log_time_ns: input.log_time_ns,
            publish_time_ns: input.publish_time_ns,
            data: &input.data,
        });
        let offset_ns = self.log_time_offset_ns;
        let event = self.detector.detect(input.topic, &input.data, |stack_ns| {
            format_utc_iso(wall_clock_ns(stack_ns, offset_ns))
        });
        self.live.enqueuer.release(input.data);
        if let Some(event) = event {
            self.on_trigger(event);
        }
        self.send_new_blocks();
    }

    fn on_trigger(&mut self, mut event: RecordedEvent) {
        self.report.triggers += 1;
        let after_ns = self.settings.after.as_nanos() as u64;
        let inside = self
            .clip
            .as_ref()
            .is_some_and(|clip| event.stamp_ns <= clip.end_ns);
        if inside {
            if let Some(clip) = self.clip.as_mut() {
                clip.end_ns = clip
                    .end_ns
                    .max(event.stamp_ns.saturating_add(after_ns))
                    .min(clip.end_limit_ns);
                event.clip = format!("{}.mcap", clip.name);
            }
            tracing::info!(kind = event.kind.name(), text = %event.text, "trigger inside an open clip: window extended");
            if !self.clips.send(ClipCommand::Event(event.clone())) {
                self.report.clip_commands_dropped += 1;
            }
        } else {
            self.close_clip();
            let before_ns = self.settings.before.as_nanos() as u64;
            let start_ns = event.stamp_ns.saturating_sub(before_ns);
            let name = self.clip_name(&event);
            event.clip = format!("{name}.mcap");
            tracing::info!(kind = event.kind.name(), text = %event.text, clip = %name, "trigger: flight-recorder clip opened");
            let blocks = self.ring.sealed_since(start_ns);
            let opened = self.clips.send(ClipCommand::Open {
                name: name.clone(),
                start_ns,
                events: vec![event.clone()],
            });
            if !opened || !self.clips.send(ClipCommand::Blocks(blocks)) {
                self.report.clip_commands_dropped += 1;
            }
            self.clip = Some(OpenClip {
                end_ns: event.stamp_ns.saturating_add(after_ns),
                end_limit_ns: start_ns.saturating_add(self.settings.max_clip.as_nanos() as u64),
                name,
                sent_seal: self.ring.seal_count(),
                left_out_at_open: self.left_out(),
            });
        }
        self.live_event(&event);
    }

    /// Messages left out of the ring so far.
    fn left_out(&self) -> u64 {
        let counts = self.ring.counts();
        counts.dropped_held + counts.dropped_too_large + self.report.dropped_behind
    }

    /// `clip-<UTC of the trigger>-<kind>`, unique in the clip directory.
    fn clip_name(&self, event: &RecordedEvent) -> String {
        let stem = format!(
            "{}-{}-{}",
            crate::clip_writer::CLIP_PREFIX,
            format_utc_compact(wall_clock_ns(event.stamp_ns, self.log_time_offset_ns)),
            event.kind.name()
        );
        let dir = &self.settings.clips.dir;
        let taken = |name: &str| {
            dir.join(format!("{name}.mcap")).exists()
                || dir.join(format!("{name}.mcap.partial")).exists()
        };
        if !taken(&stem) {
            return stem;
        }
        (1..1000)
            .map(|n| format!("{stem}-{n}"))
            .find(|name| !taken(name))
            .unwrap_or(stem)
    }

    /// Hands the blocks sealed since the last hand-over to the open clip's writer.
    fn send_new_blocks(&mut self) {
        let Some(clip) = self.clip.as_mut() else {
            return;
        };
        let seals = self.ring.seal_count();
        if seals == clip.sent_seal {
            return;
        }
        let blocks = self.ring.sealed_after(clip.sent_seal);
        clip.sent_seal = seals;
        if !self.clips.send(ClipCommand::Blocks(blocks)) {
            self.report.clip_commands_dropped += 1;
        }
    }

    fn close_clip(&mut self) {
        if self.clip.is_none() {
            return;
        }
        self.ring.seal();
        self.send_new_blocks();
        let left_out = self.left_out();
        let Some(clip) = self.clip.take() else {
            return;
        };
        let close = ClipCommand::Close {
            end_ns: clip.end_ns,
            before_ns: self.settings.before.as_nanos() as u64,
            after_ns: self.settings.after.as_nanos() as u64,
            ring_left_out: left_out - clip.left_out_at_open,
            when_closed: Instant::now(),
        };
        if !self.clips.send(close) {
            self.report.clip_commands_dropped += 1;
            tracing::warn!(clip = %clip.name, "the clip writer is behind: clip not closed");
        }
        tracing::debug!(clip = %clip.name, window_end = %self.utc(clip.end_ns), "clip window closed");
    }

    /// Writes the event into the continuous record's events channel.
    fn live_event(&mut self, event: &RecordedEvent) {
        self.live_sequence = self.live_sequence.wrapping_add(1);
        let message = QueuedMessage {
            topic: self.live.index,
            sequence: self.live_sequence,
            log_time_ns: event.stamp_ns,
            publish_time_ns: event.stamp_ns,
            data: Arc::new(event.to_json()),
        };
        if !self.live.enqueuer.try_enqueue(message) {
            tracing::warn!(
                kind = event.kind.name(),
                "the event could not be queued for the recording"
            );
        }
    }
}
