//! The flight recorder's clip writer: a thread of its own that writes each clip file from the
//! ring's sealed blocks (shared with the ring, not copied) as the flight thread hands them over,
//! so writing a clip never stalls receiving or the continuous record.
//!
//! A clip is written as `<name>.mcap.partial` and renamed to `<name>.mcap` once finished: a
//! `.mcap` clip is always complete. It holds the same layout as a segment of the continuous
//! record (raw channels at full rate, wall-clock log times, the `harvest.recording`,
//! `harvest.clock`, launch, calibration, scenario and notes records), the events channel, and a
//! `harvest.clip` record (triggers, window, what the ring covered). After each clip the oldest
//! clips are removed to keep the directory under its count and size bounds.

use crate::output_dir::list_segments;
use harvest_recording::flight_ring::Block;
use harvest_recording::metadata;
use harvest_recording::recorded_events::{RecordedEvent, events_channel};
use harvest_recording::schema::TopicInfo;
use harvest_recording::segment_writer::{ChunkSettings, ForeignChannel, SegmentWriter};
use harvest_recording::wall_clock::{ClockPair, format_utc_iso};
use mcap::records::Metadata;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::Instant;

/// File name prefix of clips (what the bounds count and remove).
pub const CLIP_PREFIX: &str = "clip";

/// Where clips go and how many are kept.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipSettings {
    pub dir: PathBuf,
    pub chunks: ChunkSettings,
    /// Clips kept at most (oldest removed first).
    pub max_count: usize,
    /// Bytes of clips kept at most (oldest removed first).
    pub max_total_bytes: u64,
}

/// What the clip writer is told, in order.
pub enum ClipCommand {
    /// Start a clip covering messages logged from `start_ns` (stack clock).
    Open {
        name: String,
        start_ns: u64,
        events: Vec<RecordedEvent>,
    },
    /// Blocks of the ring to write (their messages from `start_ns` on).
    Blocks(Vec<Arc<Block>>),
    /// Another trigger inside the clip's window.
    Event(RecordedEvent),
    /// The window closed at `end_ns` (stack clock); `when_closed` is when the flight thread
    /// closed it (the clip's latency is measured from there).
    Close {
        end_ns: u64,
        before_ns: u64,
        after_ns: u64,
        ring_left_out: u64,
        when_closed: Instant,
    },
}

/// What the clip writer did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ClipReport {
    /// Clips finished, in order.
    pub clips: Vec<PathBuf>,
    /// Clips that could not be written (the reason was logged).
    pub failed: u64,
    /// Old clips removed by the bounds.
    pub removed: u64,
    /// Longest time from a window's close to its clip file being complete, s.
    pub max_latency_s: f64,
}

/// The flight thread's handle on the clip writer.
pub struct ClipWriterHandle {
    commands: SyncSender<ClipCommand>,
    thread: JoinHandle<ClipReport>,
}

/// Commands that may wait for the clip writer (blocks are counted once per batch; a batch is
/// at most the ring's blocks).
const QUEUE_COMMANDS: usize = 1024;

impl ClipWriterHandle {
    /// Starts the thread. `topics` is the recording's catalogue table (record topic indices
    /// point into it); `recording_fields` and `session_records` go into every clip as into
    /// every segment; `log_time_offset_ns` turns stack stamps into the file's log times.
    pub fn spawn(
        settings: ClipSettings,
        topics: Vec<TopicInfo>,
        recording_fields: BTreeMap<String, String>,
        session_records: Vec<Metadata>,
        session_clock: ClockPair,
        log_time_offset_ns: i64,
    ) -> std::io::Result<Self> {
        std::fs::create_dir_all(&settings.dir)?;
        let (commands, receiver) = std::sync::mpsc::sync_channel(QUEUE_COMMANDS);
        let state = ClipWriter {
            settings,
            topics,
            events: events_channel(),
            recording_fields,
            session_records,
            session_clock,
            log_time_offset_ns,
            open: None,
            report: ClipReport::default(),
        };
        let thread = std::thread::Builder::new()
            .name("recorder-clips".to_owned())
            .spawn(move || state.run(receiver))?;
        Ok(Self { commands, thread })
    }

    /// Hands a command over; `false` when the writer is that far behind (the command is
    /// dropped: the clip misses those blocks, which its record then shows as fewer messages).
    pub fn send(&self, command: ClipCommand) -> bool {
        match self.commands.try_send(command) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => false,
        }
    }

    /// Finishes what is queued and stops the thread.
    pub fn finish(self) -> ClipReport {
        drop(self.commands);
        self.thread.join().unwrap_or_else(|_| {
            tracing::error!("the recorder's clip writer panicked");
            ClipReport::default()
        })
    }
}

struct OpenClip {
    name: String,
    partial: PathBuf,
    start_ns: u64,
    writer: SegmentWriter<BufWriter<File>>,
    events: Vec<RecordedEvent>,
    messages: u64,
    /// Earliest and latest log time written (stack clock).
    first_ns: u64,
    last_ns: u64,
    event_sequence: u32,
    failed: bool,
}

struct ClipWriter {
    settings: ClipSettings,
    topics: Vec<TopicInfo>,
    events: ForeignChannel,
    recording_fields: BTreeMap<String, String>,
    session_records: Vec<Metadata>,
    session_clock: ClockPair,
    log_time_offset_ns: i64,
    open: Option<OpenClip>,
    report: ClipReport,
}

impl ClipWriter {
    fn run(mut self, commands: Receiver<ClipCommand>) -> ClipReport {
        while let Ok(command) = commands.recv() {
            match command {
                ClipCommand::Open {
                    name,
                    start_ns,
                    events,
                } => self.open(name, start_ns, events),
                ClipCommand::Blocks(blocks) => self.write_blocks(&blocks),
                ClipCommand::Event(event) => self.write_event(event),
                ClipCommand::Close {
                    end_ns,
                    before_ns,
                    after_ns,
                    ring_left_out,
                    when_closed,
                } => self.close(end_ns, before_ns, after_ns, ring_left_out, when_closed),
            }
        }
        if let Some(clip) = self.open.take() {
            // The recorder stopped inside a window: keep what was written.
            self.open = Some(clip);
            let now_ns = harvest_ipc::MonotonicClock::read_ns();
            self.close(now_ns, 0, 0, 0, Instant::now());
        }
        self.report
    }

    fn wall_ns(&self, stack_ns: u64) -> u64 {
        crate::writer_thread::wall_clock_ns(stack_ns, self.log_time_offset_ns)
    }

    fn open(&mut self, name: String, start_ns: u64, events: Vec<RecordedEvent>) {
        if self.open.is_some() {
            // The flight thread closes a clip before opening the next; keep the old one.
            let now_ns = harvest_ipc::MonotonicClock::read_ns();
            self.close(now_ns, 0, 0, 0, Instant::now());
        }
        let partial = self.settings.dir.join(format!("{name}.mcap.partial"));
        let result = File::create(&partial)
            .map_err(|error| error.to_string())
            .and_then(|file| {
                SegmentWriter::new(
                    BufWriter::with_capacity(1 << 20, file),
                    &self.settings.chunks,
                    self.topics.len() + 1,
                )
            });
        let mut writer = match result {
            Ok(writer) => writer,
            Err(error) => {
                tracing::warn!(path = %partial.display(), %error, "cannot create a clip file");
                self.report.failed += 1;
                return;
            }
        };
        let mut recording = self.recording_fields.clone();
        recording.insert("clip".to_owned(), name.clone());
        let mut records = vec![
            Metadata {
                name: metadata::RECORDING.to_owned(),
                metadata: recording,
            },
            metadata::clock_record(self.session_clock, Some(self.log_time_offset_ns)),
        ];
        records.extend(self.session_records.iter().cloned());
        let mut failed = false;
        for record in &records {
            if let Err(error) = writer.write_metadata(record) {
                tracing::warn!(%error, "cannot write a clip's metadata");
                failed = true;
            }
        }
        let mut clip = OpenClip {
            name,
            partial,
            start_ns,
            writer,
            events: Vec::new(),
            messages: 0,
            first_ns: u64::MAX,
            last_ns: 0,
            event_sequence: 0,
            failed,
        };
        let events_index = self.topics.len();
        if let Err(error) = clip.writer.add_foreign_channel(events_index, &self.events) {
            tracing::warn!(%error, "cannot add the events channel to a clip");
            clip.failed = true;
        }
        self.open = Some(clip);
        for event in events {
            self.write_event(event);
        }
    }

    fn write_blocks(&mut self, blocks: &[Arc<Block>]) {
        let offset_ns = self.log_time_offset_ns;
        let Some(clip) = self.open.as_mut() else {
            return;
        };
        if clip.failed {
            return;
        }
        for block in blocks {
            if block.last_log_ns() < clip.start_ns {
                continue;
            }
            for record in block.records() {
                if record.log_time_ns < clip.start_ns {
                    continue;
                }
                let index = record.topic as usize;
                let Some(topic) = self.topics.get(index) else {
                    continue;
                };
                let result = clip.writer.write_message(
                    index,
                    topic,
                    record.sequence,
                    crate::writer_thread::wall_clock_ns(record.log_time_ns, offset_ns),
                    crate::writer_thread::wall_clock_ns(record.publish_time_ns, offset_ns),
                    record.data,
                );
                if let Err(error) = result {
                    tracing::warn!(clip = %clip.partial.display(), %error, "writing a clip failed");
                    clip.failed = true;
                    return;
                }
                clip.messages += 1;
                clip.first_ns = clip.first_ns.min(record.log_time_ns);
                clip.last_ns = clip.last_ns.max(record.log_time_ns);
            }
        }
    }

    fn write_event(&mut self, mut event: RecordedEvent) {
        let log_time_ns = self.wall_ns(event.stamp_ns);
        let events_index = self.topics.len();
        let Some(clip) = self.open.as_mut() else {
            return;
        };
        event.clip = format!("{}.mcap", clip.name);
        clip.event_sequence += 1;
        let result = clip.writer.write_foreign_message(
            events_index,
            &self.events,
            clip.event_sequence,
            log_time_ns,
            log_time_ns,
            &event.to_json(),
        );
        if let Err(error) = result {
            tracing::warn!(%error, "cannot write an event into a clip");
            clip.failed = true;
        }
        clip.events.push(event);
    }

    fn close(
        &mut self,
        end_ns: u64,
        before_ns: u64,
        after_ns: u64,
        ring_left_out: u64,
        when_closed: Instant,
    ) {
        let Some(mut clip) = self.open.take() else {
            return;
        };
        let utc = |stack_ns: u64| format_utc_iso(self.wall_ns(stack_ns));
        let kinds: Vec<&str> = clip.events.iter().map(|event| event.kind.name()).collect();
        let texts: Vec<&str> = clip
            .events
            .iter()
            .map(|event| event.text.as_str())
            .collect();
        let first_trigger_ns = clip.events.first().map_or(clip.start_ns, |e| e.stamp_ns);
        let covered_from_ns = if clip.messages > 0 {
            clip.first_ns
        } else {
            clip.start_ns
        };
        let record = metadata::record(
            metadata::CLIP,
            [
                ("triggers", kinds.join(",")),
                ("texts", texts.join(" | ")),
                ("first_trigger_utc", utc(first_trigger_ns)),
                ("window_start_utc", utc(clip.start_ns)),
                ("window_end_utc", utc(end_ns)),
                (
                    "window_s",
                    format!("{:.3}", end_ns.saturating_sub(clip.start_ns) as f64 * 1e-9),
                ),
                ("before_s", format!("{:.3}", before_ns as f64 * 1e-9)),
                ("after_s", format!("{:.3}", after_ns as f64 * 1e-9)),
                // Less than the window when the ring held less history than the window.
                (
                    "covered_s",
                    format!(
                        "{:.3}",
                        clip.last_ns.saturating_sub(covered_from_ns) as f64 * 1e-9
                    ),
                ),
                ("covered_from_utc", utc(covered_from_ns)),
                ("messages", clip.messages.to_string()),
                ("ring_left_out", ring_left_out.to_string()),
            ],
        );
        if let Err(error) = clip.writer.write_metadata(&record) {
            tracing::warn!(%error, "cannot write a clip's record");
            clip.failed = true;
        }
        let size_bytes = clip.writer.size_bytes();
        let finished = clip.writer.finish().map_err(|error| error.to_string());
        let path = self.settings.dir.join(format!("{}.mcap", clip.name));
        let result = finished
            .and_then(|_| std::fs::rename(&clip.partial, &path).map_err(|error| error.to_string()));
        match result {
            Ok(()) if !clip.failed => {
                let latency_s = when_closed.elapsed().as_secs_f64();
                self.report.max_latency_s = self.report.max_latency_s.max(latency_s);
                tracing::info!(
                    path = %path.display(),
                    triggers = %kinds.join(","),
                    messages = clip.messages,
                    size_bytes,
                    written_after_close_s = latency_s,
                    "flight-recorder clip written"
                );
                self.report.clips.push(path.clone());
                self.enforce_bounds(&path);
            }
            Ok(()) => {
                tracing::warn!(path = %path.display(), "clip written with errors (see above)");
                self.report.failed += 1;
            }
            Err(error) => {
                tracing::warn!(path = %clip.partial.display(), %error, "cannot finish a clip");
                self.report.failed += 1;
            }
        }
    }

    fn enforce_bounds(&mut self, keep: &Path) {
        let files = match list_segments(&self.settings.dir, CLIP_PREFIX) {
            Ok(files) => files,
            Err(error) => {
                tracing::warn!(dir = %self.settings.dir.display(), %error, "cannot list clips");
                return;
            }
        };
        let mut count = files.len();
        let mut total: u64 = files.iter().map(|file| file.size_bytes).sum();
        for file in files {
            if count <= self.settings.max_count && total <= self.settings.max_total_bytes {
                break;
            }
            if file.path == keep {
                continue;
            }
            match std::fs::remove_file(&file.path) {
                Ok(()) => {
                    tracing::info!(path = %file.path.display(), "old clip removed (clip bounds)");
                    count -= 1;
                    total = total.saturating_sub(file.size_bytes);
                    self.report.removed += 1;
                }
                Err(error) => {
                    tracing::warn!(path = %file.path.display(), %error, "cannot remove an old clip")
                }
            }
        }
    }
}
