//! The recording's writer thread: owns the open segment file, turns queued messages into
//! chunked MCAP, closes chunks on a timer (bounded loss on a crash), splits segments by size or
//! duration and keeps the recordings directory under its size bound.
//!
//! The receiving thread encodes each sample into a buffer taken from a recycling pool and hands
//! it over a bounded queue (bounded in bytes too); when the queue is full the message is
//! dropped and counted, so a slow disk never stalls receiving (nor, through iceoryx2's safe
//! overflow, any publisher).
//!
//! A queued message's bytes are shared ([`MessageBytes`]): the view thread holds the same
//! buffer as the writer instead of a copy of it (a camera frame is 6.8 MB). Whichever of the two
//! lets go of a buffer last returns it to the pool ([`reclaim`]).
//!
//! A full disk does not end the recording: the writer holds disk space ahead of what it writes
//! ([`crate::disk_space`]), so when the disk fills up it finishes the open segment (a complete
//! MCAP file ending with a `harvest.disk_full` record) and pauses. While paused, messages are
//! dropped and counted, and [`WriterHandle::is_disk_full`] tells the recorder to report itself
//! degraded. Every `disk_full_retry` the writer checks the free space, and once there is room
//! for a segment again it starts the next one. Should a write still fail for lack of space (a
//! file system without `fallocate` that something else filled), the segment is cut back to its
//! last complete record and sealed ([`harvest_recording::seal`]), and the writer pauses the
//! same way. Other write errors end the recording as before.

use crate::buffer_pool::{BufferPool, FRAME_BUFFERS};
use crate::disk_space::{OutOfSpace, SpaceReservation, free_bytes_in};
use crate::flight_thread::{FlightFeed, FlightReport};
use crate::output_dir::{create_segment, enforce_age_bound, enforce_size_bound};
use crate::video_thread::{VideoFeed, VideoReport};
use crate::view_thread::{ViewFeed, ViewReport};
use harvest_ipc::heap_trim::PeriodicHeapTrim;
use harvest_recording::mcap_error::{is_disk_full, is_out_of_space, mcap_error_text};
use harvest_recording::metadata;
use harvest_recording::recorded_events::{EVENTS_TOPIC, RecordedEvent};
use harvest_recording::schema::TopicInfo;
use harvest_recording::seal::seal_cut_file;
use harvest_recording::segment_writer::{ChunkSettings, ForeignChannel, SegmentWriter};
use harvest_recording::wall_clock::{ClockPair, format_utc_compact, format_utc_iso};
use mcap::records::Metadata;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Where and how a recording is written.
#[derive(Debug, Clone, PartialEq)]
pub struct OutputSettings {
    pub dir: PathBuf,
    /// File name prefix (`harvest`); also what the size bound counts and removes.
    pub prefix: String,
    pub domain: String,
    pub chunks: ChunkSettings,
    /// An open chunk holding messages is closed after at most this long.
    pub chunk_interval: Duration,
    /// Start a new segment file once the current one reaches this size.
    pub split_size_bytes: Option<u64>,
    /// Start a new segment file after this long.
    pub split_duration: Option<Duration>,
    /// Keep the prefix's files in `dir` under this total (oldest removed first).
    pub max_total_bytes: Option<u64>,
    /// Remove the prefix's files in `dir` last written longer ago than this.
    pub max_age: Option<Duration>,
    /// Encoded bytes allowed in flight between the receiving and the writer thread.
    pub queue_bytes: usize,
    /// While the disk is full, how often the free space is checked to resume recording.
    pub disk_full_retry: Duration,
}

/// An encoded message's bytes, shared by the writer and the view thread without copying.
pub type MessageBytes = Arc<Vec<u8>>;

/// Gives back the buffer of `bytes` when this is its last holder (`None` while another thread
/// still holds it: that one reclaims it when done).
pub fn reclaim(bytes: MessageBytes) -> Option<Vec<u8>> {
    Arc::into_inner(bytes)
}

/// One encoded message on its way to the file.
#[derive(Debug)]
pub struct QueuedMessage {
    /// Index in the recording's topic table: the catalogue topics, then the foreign channels.
    pub topic: usize,
    /// `msg_seq` of the header (MCAP stores 32 bits: wraps after 4e9 messages).
    pub sequence: u32,
    /// Receive time on the stack clock, for every channel (the catalogue's and the foreign
    /// ones): the writer adds the session's log-time offset, in one place.
    pub log_time_ns: u64,
    /// `header.publish_ns` on the stack clock (shifted by the writer like `log_time_ns`).
    pub publish_time_ns: u64,
    pub data: MessageBytes,
}

enum Command {
    AddChannel(usize),
    Message(QueuedMessage),
    Finish(Vec<Metadata>),
}

/// What the writer thread wrote.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct WriterReport {
    /// Segment files, in order.
    pub files: Vec<PathBuf>,
    /// Messages written per topic index.
    pub messages_per_topic: Vec<u64>,
    pub bytes_written: u64,
    /// Old recordings removed to stay under the size bound.
    pub removed_files: Vec<PathBuf>,
    /// Messages per topic index that reached the writer while the disk was full (not written).
    pub dropped_disk_full_per_topic: Vec<u64>,
    /// How often the disk filled up (each time, the open segment was closed).
    pub disk_full_events: u32,
}

/// Writing the recording failed.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The output directory cannot be created.
    #[error("cannot create the recordings directory {dir}: {source}")]
    CreateDir {
        dir: PathBuf,
        source: std::io::Error,
    },
    /// A segment file cannot be created.
    #[error("cannot create a recording file in {dir}: {source}")]
    CreateFile {
        dir: PathBuf,
        source: std::io::Error,
    },
    /// Writing into a segment failed (I/O error); the file keeps what was written before and
    /// can be repaired with `harvest rec recover`.
    #[error(
        "writing {file} failed: {reason}. The file is incomplete: `harvest rec recover {file} <out.mcap>` keeps what it holds"
    )]
    Write { file: PathBuf, reason: String },
    /// The disk is full (the writer pauses instead of failing).
    #[error("writing {file}: the disk is full ({reason})")]
    DiskFull { file: PathBuf, reason: String },
    /// The writer thread panicked (a bug).
    #[error("the recording writer thread panicked")]
    Panicked,
}

/// The receiving side's handle on the writer thread.
pub struct WriterHandle {
    commands: SyncSender<Command>,
    recycled: Receiver<Vec<u8>>,
    /// What other threads holding a message's buffer last return it with.
    recycle: Sender<Vec<u8>>,
    /// The encode buffers the receiving thread recycles.
    pool: BufferPool,
    queued_bytes: Arc<AtomicUsize>,
    max_queued_bytes: usize,
    failed: Arc<AtomicBool>,
    disk_full: Arc<AtomicBool>,
    thread: JoinHandle<Result<WriterReport, WriteError>>,
    /// The mapped channels' thread, when the recording has them.
    view: Option<ViewFeed>,
    /// The flight recorder's thread, when it runs.
    flight: Option<FlightFeed>,
    /// The camera's video thread, when the continuous record holds the camera as video (its
    /// raw frames then stay out of the continuous record).
    video: Option<VideoFeed>,
}

/// Queue depth in messages (the byte bound usually binds first for frames).
const QUEUE_MESSAGES: usize = 16 * 1024;
/// How often the writer thread hands the process's freed heap pages back to the kernel.
const HEAP_TRIM_PERIOD: Duration = Duration::from_secs(10);

impl WriterHandle {
    /// Creates the output directory and the first segment, then starts the writer thread.
    /// `recording_fields` go into every segment's `harvest.recording` record, `session_records`
    /// follow it. Topic indices `topics.len()..` name the `foreign` channels.
    pub fn spawn(
        settings: OutputSettings,
        topics: Vec<TopicInfo>,
        foreign: Vec<ForeignChannel>,
        recording_fields: BTreeMap<String, String>,
        session_records: Vec<Metadata>,
        session_clock: ClockPair,
    ) -> Result<Self, WriteError> {
        std::fs::create_dir_all(&settings.dir).map_err(|source| WriteError::CreateDir {
            dir: settings.dir.clone(),
            source,
        })?;
        let (commands, command_receiver) = mpsc::sync_channel(QUEUE_MESSAGES);
        let (recycle, recycled) = mpsc::channel();
        let queued_bytes = Arc::new(AtomicUsize::new(0));
        let failed = Arc::new(AtomicBool::new(false));
        let disk_full = Arc::new(AtomicBool::new(false));
        let max_queued_bytes = settings.queue_bytes;
        let pool = BufferPool::new(TopicInfo::largest_encoded_bytes(&topics));
        let mut state = WriterState {
            report: WriterReport {
                messages_per_topic: vec![0; topics.len() + foreign.len()],
                dropped_disk_full_per_topic: vec![0; topics.len() + foreign.len()],
                ..WriterReport::default()
            },
            settings,
            topics,
            foreign: foreign.into_iter().map(Arc::new).collect(),
            registered: Vec::new(),
            recording_fields,
            session_records,
            session_utc: format_utc_compact(session_clock.realtime_ns),
            log_time_offset_ns: log_time_offset_ns(session_clock),
            segment_index: 0,
            current: None,
            segment_started: Instant::now(),
            chunk_opened: None,
            pause: None,
            largest_message_bytes: 0,
            disk_full: disk_full.clone(),
            segment_events: BTreeMap::new(),
        };
        match state.open_segment() {
            Ok(()) => {}
            Err(WriteError::DiskFull { reason, .. }) => state.pause(&reason),
            Err(error) => return Err(error),
        }
        let thread_failed = failed.clone();
        let thread_queued = queued_bytes.clone();
        let thread = std::thread::Builder::new()
            .name("recorder-writer".to_owned())
            .spawn({
                let recycle = recycle.clone();
                move || state.run(command_receiver, recycle, thread_queued, thread_failed)
            })
            .map_err(|source| WriteError::CreateFile {
                dir: PathBuf::from("<writer thread>"),
                source,
            })?;
        Ok(Self {
            commands,
            recycled,
            recycle,
            pool,
            queued_bytes,
            max_queued_bytes,
            failed,
            disk_full,
            thread,
            view: None,
            flight: None,
            video: None,
        })
    }

    /// Records the camera as video from now on (its raw frames leave the continuous record).
    pub fn attach_video(&mut self, video: VideoFeed) {
        self.video = Some(video);
    }

    /// False for the catalogue topic whose raw messages stay out of the continuous record (the
    /// camera, while it is recorded as video).
    pub fn records_raw(&self, index: usize) -> bool {
        self.video
            .as_ref()
            .is_none_or(|video| !video.is_camera(index))
    }

    /// True when topic `index` is the camera and a frame received at `log_time_ns` is due for
    /// the video (takes the rate's slot).
    pub fn video_due(&mut self, index: usize, log_time_ns: u64) -> bool {
        self.video
            .as_mut()
            .is_some_and(|video| video.due(index, log_time_ns))
    }

    /// Hands a due camera frame to the video thread (shared, not copied).
    pub fn offer_video(&mut self, log_time_ns: u64, data: &MessageBytes) {
        if let Some(video) = self.video.as_mut() {
            video.offer(log_time_ns, data);
        }
    }

    /// Stops the video thread once it has encoded what it holds (before [`Self::finish`]).
    pub fn finish_video(&mut self) -> Option<VideoReport> {
        self.video.take().map(VideoFeed::finish)
    }

    /// Hands every message offered with [`Self::offer_flight`] to the flight recorder.
    pub fn attach_flight(&mut self, flight: FlightFeed) {
        self.flight = Some(flight);
    }

    /// True when the flight recorder would take a message of about `size_bytes` now.
    pub fn flight_has_room(&self, size_bytes: usize) -> bool {
        self.flight
            .as_ref()
            .is_some_and(|flight| flight.has_room(size_bytes))
    }

    /// Offers an encoded message of catalogue topic `index` to the flight recorder, if any (it
    /// shares `data`; times on the stack clock).
    pub fn offer_flight(
        &mut self,
        index: usize,
        topic: &'static str,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &MessageBytes,
    ) {
        if let Some(flight) = self.flight.as_mut() {
            flight.offer(index, topic, sequence, log_time_ns, publish_time_ns, data);
        }
    }

    /// Stops the flight recorder (an open clip is closed with what it has), before
    /// [`Self::finish`] so its last events make it into the file.
    pub fn finish_flight(&mut self) -> Option<FlightReport> {
        self.flight.take().map(FlightFeed::finish)
    }

    /// Hands the messages offered with [`Self::offer_view`] to `view` from now on.
    pub fn attach_view(&mut self, view: ViewFeed) {
        self.view = Some(view);
    }

    /// Offers an encoded message of catalogue topic `index` to the mapped channels, if any (they
    /// share `data`, they do not copy it).
    pub fn offer_view(
        &mut self,
        index: usize,
        topic: &'static str,
        log_time_ns: u64,
        data: &MessageBytes,
    ) {
        if let Some(view) = self.view.as_mut() {
            view.offer(index, topic, log_time_ns, data);
        }
    }

    /// Stops the mapped channels' thread once it has queued what it holds (before
    /// [`Self::finish`], so its last messages make it into the file).
    pub fn finish_view(&mut self) -> Option<ViewReport> {
        self.view.take().map(ViewFeed::finish)
    }

    /// True while the disk is full: the writer has closed its segment and drops messages until
    /// there is room again.
    pub fn is_disk_full(&self) -> bool {
        self.disk_full.load(Ordering::Relaxed)
    }

    /// Registers a topic in the recording (it appears in every segment, even without messages).
    pub fn add_channel(&self, topic: usize) {
        // Only fails when the writer thread is gone, which `finish` reports.
        let _ = self.commands.send(Command::AddChannel(topic));
    }

    /// True while roughly `size_bytes` more fit in the queue (never while the disk is full).
    pub fn has_room(&self, size_bytes: usize) -> bool {
        self.queued_bytes.load(Ordering::Relaxed) + size_bytes <= self.max_queued_bytes
            && !self.is_disk_full()
    }

    /// An empty buffer for encoding a message of about `size_hint` bytes (recycled when one is
    /// available, so frames do not cost a fresh allocation each).
    pub fn take_buffer(&mut self, size_hint: usize) -> Vec<u8> {
        while let Ok(buffer) = self.recycled.try_recv() {
            self.pool.give_back(buffer);
        }
        self.pool.take(size_hint)
    }

    /// Returns a buffer that was not sent.
    pub fn give_back(&mut self, buffer: Vec<u8>) {
        self.pool.give_back(buffer);
    }

    /// Returns a shared buffer that was not sent, unless another thread still holds it.
    pub fn release(&mut self, bytes: MessageBytes) {
        if let Some(buffer) = reclaim(bytes) {
            self.give_back(buffer);
        }
    }

    /// Queues a message; `false` (and the buffer returned to the pool) when the queue is full or
    /// the writer has failed.
    pub fn try_enqueue(&mut self, message: QueuedMessage) -> bool {
        let bytes = message.data.len();
        if !self.has_room(bytes) || self.has_failed() {
            self.release(message.data);
            return false;
        }
        self.queued_bytes.fetch_add(bytes, Ordering::Relaxed);
        match self.commands.try_send(Command::Message(message)) {
            Ok(()) => true,
            Err(TrySendError::Full(Command::Message(message)))
            | Err(TrySendError::Disconnected(Command::Message(message))) => {
                self.queued_bytes.fetch_sub(bytes, Ordering::Relaxed);
                self.release(message.data);
                false
            }
            Err(_) => false,
        }
    }

    /// A handle another thread queues messages with (the view thread's mapped channels), under
    /// the same byte bound.
    pub fn enqueuer(&self) -> Enqueuer {
        Enqueuer {
            commands: self.commands.clone(),
            queued_bytes: self.queued_bytes.clone(),
            max_queued_bytes: self.max_queued_bytes,
            failed: self.failed.clone(),
            recycle: self.recycle.clone(),
        }
    }

    /// True once writing failed (the error comes from [`Self::finish`]).
    pub fn has_failed(&self) -> bool {
        self.failed.load(Ordering::Relaxed) || self.thread.is_finished()
    }

    /// Writes `trailing` metadata, finishes the open segment and waits for the thread.
    pub fn finish(mut self, trailing: Vec<Metadata>) -> Result<WriterReport, WriteError> {
        tracing::info!(
            pooled = FRAME_BUFFERS,
            allocated_beyond_pool = self.pool.allocated_beyond_pool(),
            "frame buffers"
        );
        let _ = self.finish_view();
        let _ = self.finish_video();
        let _ = self.finish_flight();
        let _ = self.commands.send(Command::Finish(trailing));
        drop(self.commands);
        self.thread.join().unwrap_or(Err(WriteError::Panicked))
    }
}

/// Queues messages for the writer from another thread; drops (returns `false`) when the queue
/// is full, like [`WriterHandle::try_enqueue`].
#[derive(Debug, Clone)]
pub struct Enqueuer {
    commands: SyncSender<Command>,
    queued_bytes: Arc<AtomicUsize>,
    max_queued_bytes: usize,
    failed: Arc<AtomicBool>,
    recycle: Sender<Vec<u8>>,
}

impl Enqueuer {
    /// Lets go of a message's shared buffer: the last holder returns it to the receiving
    /// thread's pool.
    pub fn release(&self, bytes: MessageBytes) {
        if let Some(buffer) = reclaim(bytes) {
            // Only fails once the receiving side is gone; the buffer is then just freed.
            let _ = self.recycle.send(buffer);
        }
    }

    pub fn try_enqueue(&self, message: QueuedMessage) -> bool {
        let bytes = message.data.len();
        if self.queued_bytes.load(Ordering::Relaxed) + bytes > self.max_queued_bytes
            || self.failed.load(Ordering::Relaxed)
        {
            return false;
        }
        self.queued_bytes.fetch_add(bytes, Ordering::Relaxed);
        match self.commands.try_send(Command::Message(message)) {
            Ok(()) => true,
            Err(_) => {
                self.queued_bytes.fetch_sub(bytes, Ordering::Relaxed);
                false
            }
        }
    }
}

/// The log-time offset of a session: realtime minus monotonic of its clock pair.
pub fn log_time_offset_ns(session_clock: ClockPair) -> i64 {
    i64::try_from(session_clock.realtime_offset_ns()).unwrap_or(0)
}

/// A stack-clock stamp as a file log time (saturating).
pub fn wall_clock_ns(stack_ns: u64, offset_ns: i64) -> u64 {
    (i128::from(stack_ns) + i128::from(offset_ns)).clamp(0, i128::from(u64::MAX)) as u64
}

/// The segment being written.
struct OpenSegment {
    path: PathBuf,
    writer: SegmentWriter<BufWriter<File>>,
    /// Disk space held ahead of what `writer` has written.
    space: SpaceReservation,
}

/// The writer is paused: the disk was full.
struct DiskFullPause {
    /// When the free space was last checked.
    checked: Instant,
}

/// Free space on top of two chunks and two of the largest messages that a paused writer
/// waits for before it starts a segment again (so it does not flap open and closed).
const RESUME_MARGIN_BYTES: u64 = 16 << 20;

struct WriterState {
    settings: OutputSettings,
    topics: Vec<TopicInfo>,
    /// Channels of their own schema (the mapped Foxglove channels), indices after `topics`.
    foreign: Vec<Arc<ForeignChannel>>,
    /// Topic indices registered so far, re-added to each new segment.
    registered: Vec<usize>,
    recording_fields: BTreeMap<String, String>,
    session_records: Vec<Metadata>,
    session_utc: String,
    /// Added to the stack-clock stamps of every message to make the file's log and publish
    /// times (Unix-epoch ns; one offset for the whole session, so segments line up).
    log_time_offset_ns: i64,
    segment_index: u32,
    current: Option<OpenSegment>,
    segment_started: Instant,
    /// When the open chunk got its first message.
    chunk_opened: Option<Instant>,
    report: WriterReport,
    /// Set while the disk is full.
    pause: Option<DiskFullPause>,
    /// The largest message seen so far (sizes the room needed to resume).
    largest_message_bytes: u64,
    /// Shared with the handle: true while paused.
    disk_full: Arc<AtomicBool>,
    /// Events written into the open segment, by kind (its `harvest.events` record).
    segment_events: BTreeMap<&'static str, u64>,
}

impl WriterState {
    fn run(
        mut self,
        commands: Receiver<Command>,
        recycle: Sender<Vec<u8>>,
        queued_bytes: Arc<AtomicUsize>,
        failed: Arc<AtomicBool>,
    ) -> Result<WriterReport, WriteError> {
        let mut failure: Option<WriteError> = None;
        let idle_wait = self
            .settings
            .chunk_interval
            .min(Duration::from_secs(1))
            .max(Duration::from_millis(1));
        // The recorder's threads allocate and free large transient buffers (chunks, clips,
        // encoded images): freed pages go back to the kernel now and then, off the tap's path,
        // so the private memory follows what is in use.
        let mut heap_trim = PeriodicHeapTrim::new(HEAP_TRIM_PERIOD);
        loop {
            heap_trim.run_if_due();
            let wait = match self.chunk_opened {
                Some(opened) => self
                    .settings
                    .chunk_interval
                    .saturating_sub(opened.elapsed()),
                None => idle_wait,
            };
            let result = match commands.recv_timeout(wait) {
                Ok(Command::Message(message)) => {
                    queued_bytes.fetch_sub(message.data.len(), Ordering::Relaxed);
                    let result = if failure.is_none() {
                        self.write(&message)
                    } else {
                        Ok(())
                    };
                    if let Some(buffer) = reclaim(message.data) {
                        let _ = recycle.send(buffer);
                    }
                    result
                }
                Ok(Command::AddChannel(topic)) => {
                    if !self.registered.contains(&topic) {
                        self.registered.push(topic);
                    }
                    if failure.is_none() {
                        self.add_channel(topic)
                    } else {
                        Ok(())
                    }
                }
                Ok(Command::Finish(trailing)) => {
                    if failure.is_none()
                        && let Err(error) = self.finish_segment(&trailing)
                    {
                        failure = Some(error);
                    }
                    break;
                }
                Err(RecvTimeoutError::Timeout) => {
                    if failure.is_none() {
                        self.on_timer()
                    } else {
                        Ok(())
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    if failure.is_none()
                        && let Err(error) = self.finish_segment(&[])
                    {
                        failure = Some(error);
                    }
                    break;
                }
            };
            match result {
                Ok(()) => {}
                Err(WriteError::DiskFull { file, reason }) => {
                    tracing::warn!(file = %file.display(), %reason, "writing failed: the disk is full");
                    self.seal_after_failure();
                    self.pause(&reason);
                }
                Err(error) => {
                    tracing::error!(%error, "recording writer failed; dropping further messages");
                    failed.store(true, Ordering::Relaxed);
                    failure = Some(error);
                    // The segment keeps what was written: its complete chunks stay recoverable.
                    // (Dropping the MCAP writer attempts its summary once more and ignores
                    // errors.)
                    if let Some(segment) = self.current.take() {
                        self.report.files.push(segment.path);
                        self.report.bytes_written += segment.writer.size_bytes();
                    }
                }
            }
        }
        match failure {
            Some(error) => Err(error),
            None => Ok(self.report),
        }
    }

    fn segment_path(&self) -> PathBuf {
        self.current
            .as_ref()
            .map(|segment| segment.path.clone())
            .unwrap_or_default()
    }

    fn write_error(&self, error: &mcap::McapError) -> WriteError {
        let file = self.segment_path();
        let reason = mcap_error_text(error);
        if is_disk_full(error) {
            WriteError::DiskFull { file, reason }
        } else {
            WriteError::Write { file, reason }
        }
    }

    /// Closes the segment for a full disk (its room held ahead takes the rest of the file)
    /// and pauses.
    fn close_for_disk_full(&mut self, full: &OutOfSpace) {
        let record = Metadata {
            name: metadata::DISK_FULL.to_owned(),
            metadata: BTreeMap::from([
                ("dir".to_owned(), self.settings.dir.display().to_string()),
                ("free_bytes".to_owned(), full.free_bytes.to_string()),
                ("needed_bytes".to_owned(), full.needed_bytes.to_string()),
                (
                    "closed_utc".to_owned(),
                    format_utc_iso(ClockPair::now().realtime_ns),
                ),
            ]),
        };
        match self.finish_segment(&[record]) {
            Ok(()) => {}
            Err(error) => {
                tracing::warn!(%error, "cannot finish the segment on the full disk");
                self.seal_after_failure();
            }
        }
        self.pause(&full.to_string());
    }

    /// Pauses writing until the disk has room again.
    fn pause(&mut self, reason: &str) {
        if self.pause.is_none() {
            self.report.disk_full_events += 1;
            tracing::warn!(
                dir = %self.settings.dir.display(),
                %reason,
                retry_s = self.settings.disk_full_retry.as_secs_f64(),
                "the recording disk is full: recording paused (messages are dropped and counted) until there is room"
            );
        }
        self.pause = Some(DiskFullPause {
            checked: Instant::now(),
        });
        self.chunk_opened = None;
        self.disk_full.store(true, Ordering::Relaxed);
    }

    /// While paused: starts the next segment once the disk has room for it.
    fn try_resume(&mut self) -> Result<(), WriteError> {
        let Some(pause) = self.pause.as_mut() else {
            return Ok(());
        };
        if pause.checked.elapsed() < self.settings.disk_full_retry {
            return Ok(());
        }
        pause.checked = Instant::now();
        let needed_bytes = 2 * (self.settings.chunks.chunk_size_bytes + self.largest_message_bytes)
            + RESUME_MARGIN_BYTES;
        let free_bytes = match free_bytes_in(&self.settings.dir) {
            Ok(free_bytes) => free_bytes,
            Err(error) => {
                tracing::debug!(%error, "cannot read the free space");
                return Ok(());
            }
        };
        if free_bytes < needed_bytes {
            tracing::debug!(free_bytes, needed_bytes, "the recording disk is still full");
            return Ok(());
        }
        self.segment_index += 1;
        match self.open_segment() {
            Ok(()) => {
                self.pause = None;
                self.disk_full.store(false, Ordering::Relaxed);
                tracing::info!(
                    path = %self.segment_path().display(),
                    free_bytes,
                    "the recording disk has room again: recording resumes"
                );
                Ok(())
            }
            Err(WriteError::DiskFull { reason, .. }) => {
                self.pause(&reason);
                Ok(())
            }
            Err(error) => Err(error),
        }
    }

    /// After a write failed for lack of space: cuts the segment back to its last complete
    /// record and seals it, so it reads to its end.
    fn seal_after_failure(&mut self) {
        let Some(segment) = self.current.take() else {
            return;
        };
        self.chunk_opened = None;
        let complete_bytes = segment.writer.flushed_bytes();
        let (mut file, _unwritten) = segment.writer.into_stream().into_parts();
        let size_bytes = match seal_cut_file(&mut file, complete_bytes) {
            Ok(size_bytes) => {
                tracing::warn!(
                    path = %segment.path.display(),
                    size_bytes,
                    "segment cut back to its last complete record and sealed"
                );
                size_bytes
            }
            Err(error) => {
                tracing::warn!(
                    path = %segment.path.display(),
                    %error,
                    "segment left cut without an end: `harvest rec recover` reads it"
                );
                complete_bytes
            }
        };
        self.report.files.push(segment.path);
        self.report.bytes_written += size_bytes;
    }

    fn open_segment(&mut self) -> Result<(), WriteError> {
        let dir = self.settings.dir.clone();
        let (path, file) = create_segment(
            &dir,
            &self.settings.prefix,
            &self.settings.domain,
            &self.session_utc,
            self.segment_index,
        )
        .map_err(|source| {
            if is_out_of_space(&source) {
                WriteError::DiskFull {
                    file: dir.clone(),
                    reason: source.to_string(),
                }
            } else {
                WriteError::CreateFile {
                    dir: dir.clone(),
                    source,
                }
            }
        })?;
        let space = SpaceReservation::new(&file).map_err(|source| WriteError::CreateFile {
            dir: dir.clone(),
            source,
        })?;
        let writer = SegmentWriter::new(
            BufWriter::with_capacity(1 << 20, file),
            &self.settings.chunks,
            self.topics.len() + self.foreign.len(),
        )
        .map_err(|reason| WriteError::Write {
            file: path.clone(),
            reason,
        })?;
        self.current = Some(OpenSegment {
            path: path.clone(),
            writer,
            space,
        });
        self.segment_started = Instant::now();
        self.chunk_opened = None;
        if let Err(error) = self.start_segment() {
            // Nothing of value is in the new file: remove it.
            if let Some(segment) = self.current.take() {
                drop(segment.writer.into_stream().into_parts());
                let _ = std::fs::remove_file(&segment.path);
            }
            return Err(error);
        }
        tracing::info!(path = %path.display(), segment = self.segment_index, "recording to");
        if let Some(max_total_bytes) = self.settings.max_total_bytes {
            match enforce_size_bound(&dir, &self.settings.prefix, max_total_bytes, Some(&path)) {
                Ok(removed) => self
                    .report
                    .removed_files
                    .extend(removed.into_iter().map(|f| f.path)),
                Err(error) => {
                    tracing::warn!(dir = %dir.display(), %error, "cannot apply the size bound")
                }
            }
        }
        if let Some(max_age) = self.settings.max_age {
            match enforce_age_bound(
                &dir,
                &self.settings.prefix,
                max_age,
                std::time::SystemTime::now(),
                Some(&path),
            ) {
                Ok(removed) => self
                    .report
                    .removed_files
                    .extend(removed.into_iter().map(|f| f.path)),
                Err(error) => {
                    tracing::warn!(dir = %dir.display(), %error, "cannot apply the age bound")
                }
            }
        }
        Ok(())
    }

    /// Writes the new segment's metadata records and channels, holds room for them and for
    /// finishing the file, and hands them to the disk.
    fn start_segment(&mut self) -> Result<(), WriteError> {
        let clock = ClockPair::now();
        let mut recording = self.recording_fields.clone();
        recording.insert("segment".to_owned(), self.segment_index.to_string());
        recording.insert(
            "segment_started_utc".to_owned(),
            format_utc_iso(clock.realtime_ns),
        );
        let mut records = vec![
            Metadata {
                name: metadata::RECORDING.to_owned(),
                metadata: recording,
            },
            metadata::clock_record(clock, Some(self.log_time_offset_ns)),
        ];
        records.extend(self.session_records.iter().cloned());
        for record in &records {
            self.with_segment(|segment| segment.write_metadata(record))?;
        }
        for topic in self.registered.clone() {
            self.add_channel(topic)?;
        }
        if let Err(full) = self.reserve_room(0) {
            return Err(WriteError::DiskFull {
                file: self.segment_path(),
                reason: full.to_string(),
            });
        }
        self.with_segment(|segment| segment.flush())
    }

    /// Holds disk space for `message_bytes` more and for finishing the file after them.
    fn reserve_room(&mut self, message_bytes: u64) -> Result<(), OutOfSpace> {
        let Some(segment) = self.current.as_mut() else {
            return Ok(());
        };
        let written_bytes = segment.writer.size_bytes();
        let end_bytes = written_bytes + segment.writer.finish_bound_bytes(message_bytes);
        segment.space.ensure(end_bytes, written_bytes)
    }

    fn with_segment(
        &mut self,
        operation: impl FnOnce(&mut SegmentWriter<BufWriter<File>>) -> Result<(), mcap::McapError>,
    ) -> Result<(), WriteError> {
        let result = match self.current.as_mut() {
            Some(segment) => operation(&mut segment.writer),
            None => return Ok(()),
        };
        result.map_err(|error| self.write_error(&error))
    }

    fn add_channel(&mut self, topic: usize) -> Result<(), WriteError> {
        if let Some(info) = self.topics.get(topic).copied() {
            return self.with_segment(|segment| segment.add_channel(topic, &info).map(|_| ()));
        }
        let Some(foreign) = self.foreign.get(topic - self.topics.len()).cloned() else {
            return Ok(());
        };
        self.with_segment(|segment| segment.add_foreign_channel(topic, &foreign).map(|_| ()))
    }

    fn write(&mut self, message: &QueuedMessage) -> Result<(), WriteError> {
        let info = self.topics.get(message.topic).copied();
        let foreign = match info {
            Some(_) => None,
            None => match self.foreign.get(message.topic - self.topics.len()) {
                Some(foreign) => Some(Arc::clone(foreign)),
                None => return Ok(()),
            },
        };
        let message_bytes = message.data.len() as u64;
        self.largest_message_bytes = self.largest_message_bytes.max(message_bytes);
        if self.pause.is_some() {
            self.try_resume()?;
        }
        if self.pause.is_none() && self.current.is_none() {
            self.open_segment()?;
        }
        if self.pause.is_none()
            && let Err(full) = self.reserve_room(message_bytes)
        {
            self.close_for_disk_full(&full);
        }
        if self.pause.is_some() {
            if let Some(count) = self
                .report
                .dropped_disk_full_per_topic
                .get_mut(message.topic)
            {
                *count += 1;
            }
            return Ok(());
        }
        let offset_ns = self.log_time_offset_ns;
        self.with_segment(|segment| match (&info, &foreign) {
            (Some(info), _) => segment.write_message(
                message.topic,
                info,
                message.sequence,
                wall_clock_ns(message.log_time_ns, offset_ns),
                wall_clock_ns(message.publish_time_ns, offset_ns),
                &message.data,
            ),
            (None, Some(foreign)) => segment.write_foreign_message(
                message.topic,
                foreign,
                message.sequence,
                wall_clock_ns(message.log_time_ns, offset_ns),
                wall_clock_ns(message.publish_time_ns, offset_ns),
                &message.data,
            ),
            (None, None) => Ok(()),
        })?;
        if let Some(count) = self.report.messages_per_topic.get_mut(message.topic) {
            *count += 1;
        }
        if foreign.as_ref().is_some_and(|f| f.topic == EVENTS_TOPIC)
            && let Some(event) = RecordedEvent::from_json(&message.data)
        {
            *self.segment_events.entry(event.kind.name()).or_insert(0) += 1;
        }
        tracing::trace!(
            topic = message.topic,
            bytes = message.data.len(),
            "message written"
        );
        if self.chunk_opened.is_none() {
            self.chunk_opened = Some(Instant::now());
        }
        if self
            .chunk_opened
            .is_some_and(|opened| opened.elapsed() >= self.settings.chunk_interval)
        {
            self.close_chunk()?;
        }
        self.split_if_due()
    }

    fn close_chunk(&mut self) -> Result<(), WriteError> {
        self.chunk_opened = None;
        self.with_segment(|segment| segment.close_chunk())
    }

    fn on_timer(&mut self) -> Result<(), WriteError> {
        if self.pause.is_some() {
            return self.try_resume();
        }
        if self
            .chunk_opened
            .is_some_and(|opened| opened.elapsed() >= self.settings.chunk_interval)
        {
            self.close_chunk()?;
        }
        self.split_if_due()
    }

    fn split_if_due(&mut self) -> Result<(), WriteError> {
        let Some(segment) = self.current.as_ref() else {
            return Ok(());
        };
        let by_size = self
            .settings
            .split_size_bytes
            .is_some_and(|limit| segment.writer.size_bytes() >= limit);
        let by_time = self.settings.split_duration.is_some_and(|limit| {
            self.segment_started.elapsed() >= limit && segment.writer.message_count() > 0
        });
        if by_size || by_time {
            self.finish_segment(&[])?;
            self.segment_index += 1;
            self.open_segment()?;
        }
        Ok(())
    }

    fn finish_segment(&mut self, trailing: &[Metadata]) -> Result<(), WriteError> {
        if self.current.is_some() && !self.segment_events.is_empty() {
            let counts = std::mem::take(&mut self.segment_events);
            let record = metadata::record(
                metadata::EVENTS,
                counts
                    .iter()
                    .map(|(kind, count)| (*kind, count.to_string())),
            );
            self.with_segment(|segment| segment.write_metadata(&record))?;
        }
        for record in trailing {
            self.with_segment(|segment| segment.write_metadata(record))?;
        }
        let Some(segment) = self.current.take() else {
            return Ok(());
        };
        self.chunk_opened = None;
        let size_bytes = segment.writer.size_bytes();
        let result = segment.writer.finish();
        self.report.files.push(segment.path.clone());
        self.report.bytes_written += size_bytes;
        match result {
            Ok(_) => {
                segment.space.release();
                tracing::info!(path = %segment.path.display(), size_bytes, "recording segment finished");
                Ok(())
            }
            Err(error) => {
                let reason = mcap_error_text(&error);
                if is_disk_full(&error) {
                    Err(WriteError::DiskFull {
                        file: segment.path,
                        reason,
                    })
                } else {
                    Err(WriteError::Write {
                        file: segment.path,
                        reason,
                    })
                }
            }
        }
    }
}
