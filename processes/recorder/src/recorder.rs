//! `harvest recorder`: taps every selected catalogue channel of the domain and writes it to
//! MCAP (see the crate docs for the file layout).
//!
//! The loop is the ipc wait set: each subscriber's listener wakes it when data arrives; a
//! housekeeping interval sends heartbeats, retries channels that could not be opened yet,
//! watches the writer and the stop flag. SIGINT/SIGTERM end the loop; the recorder then drains
//! what is still queued, writes per-channel drop counts and finishes the file.

use crate::clip_writer::ClipSettings;
use crate::flight_thread::{FlightFeed, FlightSettings, LiveEvents};
use crate::tap::{Tap, TapCounts, TypedTap};
use crate::video_thread::{VideoChannels, VideoFeed, VideoFeedSettings, VideoReport};
use crate::view_thread::{self, ViewFeed};
use crate::writer_thread::{OutputSettings, WriteError, WriterHandle, log_time_offset_ns};
use harvest_foxglove_mapping::Mounting;
use harvest_foxglove_mapping::mounting_files::{camera_from_lidar_file, robot_from_camera_file};
use harvest_ipc::catalogue::{self, Layer};
use harvest_ipc::payloads::ProcessRunState;
use harvest_ipc::{
    Channel, ChannelVisitor, Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, Payload,
    RunEnd, RunError, Waiter,
};
use harvest_recording::camera_record::{DEPTH_TOPIC, VIDEO_TOPIC, depth_channel, video_channel};
use harvest_recording::flight_ring::RECORD_HEADER_BYTES;
use harvest_recording::metadata;
use harvest_recording::recorded_events::events_channel;
use harvest_recording::schema::{TopicInfo, catalogue_topics, layer_name};
use harvest_recording::segment_writer::{ChunkCompression, ChunkSettings};
use harvest_recording::topic_filter::TopicFilter;
use harvest_recording::units::{format_bytes, parse_duration, parse_size_bytes};
use harvest_recording::video_codec::VideoSettings;
use harvest_recording::wall_clock::{ClockPair, format_utc_iso};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Catalogue layers on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum LayerArg {
    Stack,
    Hardware,
    Evaluation,
}

impl LayerArg {
    pub fn layer(self) -> Layer {
        match self {
            Self::Stack => Layer::Stack,
            Self::Hardware => Layer::Hardware,
            Self::Evaluation => Layer::Evaluation,
        }
    }
}

/// Options of `harvest recorder`.
#[derive(Debug, Clone, clap::Args)]
pub struct RecorderArgs {
    /// Directory the recording segments are written to.
    #[arg(long, default_value = "recordings")]
    pub output_dir: PathBuf,
    /// File name prefix; the size bound only counts and removes `<prefix>-*.mcap` files.
    #[arg(long, default_value = "harvest")]
    pub prefix: String,
    /// Chunk compression. zstd by default: with the camera recorded as video the continuous
    /// record's channels are small. With `--camera raw` use lz4 (zstd level 1, about 170 MB/s
    /// here, does not keep up with 30 Hz raw frames for long; lz4 does).
    #[arg(long, default_value = "zstd")]
    pub compression: ChunkCompression,
    /// Compression level (default: zstd 1, lz4 0 = fast default).
    #[arg(long)]
    pub compression_level: Option<u32>,
    /// zstd worker threads (0: compress on the writer thread itself).
    #[arg(long, default_value_t = 1)]
    pub compression_threads: u32,
    /// Uncompressed size at which a chunk is closed (e.g. 4MiB).
    #[arg(long, default_value = "4MiB", value_parser = parse_size_bytes)]
    pub chunk_size: u64,
    /// A chunk is also closed after this long, bounding what a crash can lose (e.g. 1s).
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    pub chunk_interval: Duration,
    /// Start a new segment file at this size (0: never split by size).
    #[arg(long, default_value = "1GiB", value_parser = parse_size_bytes)]
    pub split_size: u64,
    /// Start a new segment file after this long (0s: only by size). The open segment's index
    /// (one MCAP chunk index per chunk, kept for the file's summary) grows with its length and is
    /// freed at the split, so this also bounds that memory.
    #[arg(long, default_value = "5m", value_parser = parse_duration)]
    pub split_duration: Option<Duration>,
    /// Bound on the total size of `<prefix>-*.mcap` files in the output directory; the oldest
    /// are removed first when a segment starts (0: unbounded).
    #[arg(long, default_value = "20GiB", value_parser = parse_size_bytes)]
    pub max_total_size: u64,
    /// Bound on the age of `<prefix>-*.mcap` files in the output directory: when a segment
    /// starts, those last written longer ago are removed (e.g. 168h; none: no age bound).
    #[arg(long, value_parser = parse_duration)]
    pub max_age: Option<Duration>,
    /// How the camera (`camera/rgbd`) goes into the continuous record: `video` (H.264 on
    /// `camera/video` at `--video-rate`, depth on `camera/depth` at `--depth-rate`) or `raw`
    /// (every frame as it is, 6.8 MB each). Clips always hold the raw frames.
    #[arg(long, value_enum, default_value = "video")]
    pub camera: CameraRecord,
    /// Frames per second of the camera video.
    #[arg(long, default_value_t = 10.0)]
    pub video_rate: f64,
    /// Target bit rate of the camera video, bits per second.
    #[arg(long, default_value_t = 2_000_000)]
    pub video_bitrate: u32,
    /// Depth images per second in the continuous record (each one with the video frame of the
    /// same capture; at most the video rate).
    #[arg(long, default_value_t = 2.0)]
    pub depth_rate: f64,
    /// Record only topics matching one of these globs (`*` matches across `/`); repeatable.
    #[arg(long = "include", value_name = "GLOB")]
    pub include: Vec<String>,
    /// Leave out topics matching one of these globs; repeatable.
    #[arg(long = "exclude", value_name = "GLOB")]
    pub exclude: Vec<String>,
    /// Catalogue layers to record; repeatable. Default: the stack layer only (hardware
    /// channels duplicate what drivers republish, evaluation channels are ground truth).
    #[arg(long = "layer", value_enum, default_value = "stack")]
    pub layers: Vec<LayerArg>,
    /// Encoded bytes that may wait for the disk before messages are dropped (and counted).
    #[arg(long, default_value = "512MiB", value_parser = parse_size_bytes)]
    pub queue_size: u64,
    /// Launch file of the stack, stored in the recording's metadata.
    #[arg(long)]
    pub launch_file: Option<PathBuf>,
    /// Calibration file, stored in the recording's metadata; its `robot_from_camera` also
    /// places the camera in the mapped 3D view.
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// LiDAR extrinsic file (`camera_from_lidar`): places the LiDAR cloud in the mapped 3D view.
    #[arg(long, value_name = "PATH")]
    pub lidar_extrinsic: Option<PathBuf>,
    /// Record only the raw channels: leave out the channels mapped to Foxglove's schemas
    /// (protobuf, at the viewing rates) that let the file open in Foxglove as it is.
    #[arg(long)]
    pub no_foxglove: bool,
    /// Scenario name or file, stored in the recording's metadata.
    #[arg(long)]
    pub scenario: Option<String>,
    /// Extra `key=value` metadata; repeatable.
    #[arg(long = "note", value_name = "KEY=VALUE")]
    pub notes: Vec<String>,
    /// RAM of the flight recorder's ring: every recorded channel at full rate (0: no flight
    /// recorder). Allocated and made resident once, at start. The default stack's raw channels take
    /// about 125 MB/s, so 2 GiB holds about 16 s.
    #[arg(long, default_value = "2GiB", value_parser = parse_size_bytes)]
    pub flight_ring_size: u64,
    /// Window a clip keeps before its trigger (a failed attempt, a safety violation, the e-stop
    /// engaged, `harvest ctl mark`).
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub clip_before: Duration,
    /// Window a clip keeps after its last trigger.
    #[arg(long, default_value = "5s", value_parser = parse_duration)]
    pub clip_after: Duration,
    /// Longest clip: triggers inside an open window extend it up to this.
    #[arg(long, default_value = "120s", value_parser = parse_duration)]
    pub clip_max_duration: Duration,
    /// Directory of the clips (default: `<output-dir>/clips`).
    #[arg(long)]
    pub clip_dir: Option<PathBuf>,
    /// Clips kept at most (the oldest removed first).
    #[arg(long, default_value_t = 20)]
    pub clip_max_count: usize,
    /// Total size of the clips kept at most (the oldest removed first).
    #[arg(long, default_value = "20GiB", value_parser = parse_size_bytes)]
    pub clip_max_total_size: u64,
    /// How often channels that could not be opened are retried, and how often the free space
    /// is checked while the disk is full (recording resumes in a new segment once there is
    /// room again).
    #[arg(long, default_value = "1s", value_parser = parse_duration)]
    pub retry_interval: Duration,
}

/// How the camera goes into the continuous record.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CameraRecord {
    /// H.264 video and depth at a reduced rate.
    Video,
    /// Every raw frame.
    Raw,
}

impl Default for RecorderArgs {
    fn default() -> Self {
        Self {
            output_dir: PathBuf::from("recordings"),
            prefix: "harvest".to_owned(),
            compression: ChunkCompression::Zstd,
            compression_level: None,
            compression_threads: 1,
            chunk_size: 4 << 20,
            chunk_interval: Duration::from_secs(1),
            split_size: 1 << 30,
            split_duration: Some(Duration::from_secs(300)),
            max_total_size: 20 << 30,
            max_age: None,
            camera: CameraRecord::Video,
            video_rate: 10.0,
            video_bitrate: 2_000_000,
            depth_rate: 2.0,
            include: Vec::new(),
            exclude: Vec::new(),
            layers: vec![LayerArg::Stack],
            queue_size: 512 << 20,
            launch_file: None,
            calibration: None,
            lidar_extrinsic: None,
            no_foxglove: false,
            scenario: None,
            notes: Vec::new(),
            flight_ring_size: 2 << 30,
            clip_before: Duration::from_secs(10),
            clip_after: Duration::from_secs(5),
            clip_max_duration: Duration::from_secs(120),
            clip_dir: None,
            clip_max_count: 20,
            clip_max_total_size: 20 << 30,
            retry_interval: Duration::from_secs(1),
        }
    }
}

impl RecorderArgs {
    /// The topic selection these options describe.
    pub fn topic_filter(&self) -> TopicFilter {
        TopicFilter {
            include: self.include.clone(),
            exclude: self.exclude.clone(),
            layers: self.layers.iter().map(|layer| layer.layer()).collect(),
        }
    }

    fn chunk_settings(&self) -> ChunkSettings {
        let default_level = match self.compression {
            ChunkCompression::Zstd => 1,
            ChunkCompression::Lz4 | ChunkCompression::None => 0,
        };
        ChunkSettings {
            compression: self.compression,
            compression_level: self.compression_level.unwrap_or(default_level),
            compression_threads: self.compression_threads,
            chunk_size_bytes: self.chunk_size,
        }
    }

    /// The flight recorder's settings (`None` with `--flight-ring-size 0`).
    pub fn flight_settings(&self, topics: &[TopicInfo]) -> Option<FlightSettings> {
        if self.flight_ring_size == 0 {
            return None;
        }
        // A block holds the largest recorded message (a camera frame) with room to spare.
        let largest = TopicInfo::largest_encoded_bytes(topics);
        let block_bytes = (largest + largest / 4 + RECORD_HEADER_BYTES).max(1 << 20);
        let compression = match self.compression {
            ChunkCompression::None => ChunkCompression::None,
            _ => ChunkCompression::Lz4,
        };
        Some(FlightSettings {
            ring_bytes: usize::try_from(self.flight_ring_size).unwrap_or(usize::MAX),
            block_bytes,
            before: self.clip_before,
            after: self.clip_after,
            max_clip: self
                .clip_max_duration
                .max(self.clip_before + self.clip_after),
            clips: ClipSettings {
                dir: self
                    .clip_dir
                    .clone()
                    .unwrap_or_else(|| self.output_dir.join("clips")),
                chunks: ChunkSettings {
                    compression,
                    compression_level: 0,
                    compression_threads: 0,
                    chunk_size_bytes: self.chunk_size,
                },
                max_count: self.clip_max_count.max(1),
                max_total_bytes: self.clip_max_total_size,
            },
        })
    }

    /// The camera video's settings (`None` with `--camera raw`), after checking the rates.
    pub fn video_settings(&self) -> Result<Option<VideoFeedSettings>, RecorderError> {
        if self.camera == CameraRecord::Raw {
            return Ok(None);
        }
        if !(self.video_rate > 0.0 && self.video_rate <= 60.0) {
            return Err(RecorderError::InvalidOption {
                option: "--video-rate",
                value: self.video_rate.to_string(),
                reason: "must be in (0, 60] frames per second".to_owned(),
            });
        }
        if !(self.depth_rate > 0.0 && self.depth_rate.is_finite()) {
            return Err(RecorderError::InvalidOption {
                option: "--depth-rate",
                value: self.depth_rate.to_string(),
                reason: "must be a positive number of images per second".to_owned(),
            });
        }
        if self.video_bitrate < 100_000 {
            return Err(RecorderError::InvalidOption {
                option: "--video-bitrate",
                value: self.video_bitrate.to_string(),
                reason: "must be at least 100000 bits per second".to_owned(),
            });
        }
        let depth_every = (self.video_rate / self.depth_rate).round().max(1.0) as u32;
        Ok(Some(VideoFeedSettings {
            video: VideoSettings::at_rate(self.video_rate, self.video_bitrate),
            depth_every,
        }))
    }

    /// Output settings, after checking the options fit together.
    pub fn output_settings(&self, domain: &Domain) -> Result<OutputSettings, RecorderError> {
        let nonzero = |value: u64| (value > 0).then_some(value);
        let settings = OutputSettings {
            dir: self.output_dir.clone(),
            prefix: self.prefix.clone(),
            domain: domain.name().to_owned(),
            chunks: self.chunk_settings(),
            chunk_interval: self.chunk_interval.max(Duration::from_millis(1)),
            split_size_bytes: nonzero(self.split_size),
            split_duration: self.split_duration.filter(|duration| !duration.is_zero()),
            max_total_bytes: nonzero(self.max_total_size),
            max_age: self.max_age.filter(|age| !age.is_zero()),
            queue_bytes: usize::try_from(self.queue_size).unwrap_or(usize::MAX),
            disk_full_retry: self.retry_interval,
        };
        if self.prefix.is_empty() || self.prefix.contains('/') {
            return Err(RecorderError::InvalidOption {
                option: "--prefix",
                value: self.prefix.clone(),
                reason: "must be a non-empty file-name fragment without '/'".to_owned(),
            });
        }
        if self.compression == ChunkCompression::Zstd && settings.chunks.compression_level > 22 {
            return Err(RecorderError::InvalidOption {
                option: "--compression-level",
                value: settings.chunks.compression_level.to_string(),
                reason: "zstd levels are 1..=22".to_owned(),
            });
        }
        if let Some(max_total) = settings.max_total_bytes {
            match settings.split_size_bytes {
                Some(split) if split.saturating_mul(2) <= max_total => {}
                _ => tracing::warn!(
                    max_total = %format_bytes(max_total),
                    "the size bound only removes finished segments: use --split-size of at most half of --max-total-size"
                ),
            }
        }
        Ok(settings)
    }
}

/// Controls a recorder run from another thread (tests, embedding).
#[derive(Debug)]
pub struct RecorderControl {
    /// Set to end the recording; checked every `housekeeping_period`.
    pub stop: AtomicBool,
    /// Set by the recorder once every channel it could open is tapped.
    pub ready: AtomicBool,
    /// How often the recorder checks `stop`, retries channels and considers a heartbeat.
    pub housekeeping_period: Duration,
}

impl RecorderControl {
    pub fn new(housekeeping_period: Duration) -> Self {
        Self {
            stop: AtomicBool::new(false),
            ready: AtomicBool::new(false),
            housekeeping_period,
        }
    }
}

impl Default for RecorderControl {
    fn default() -> Self {
        Self::new(HEARTBEAT_PERIOD / 2)
    }
}

/// Why the recording ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordingEnd {
    /// SIGINT or SIGTERM.
    Signal,
    /// The control's stop flag.
    Stopped,
}

/// One channel's line of the end-of-recording report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicReport {
    pub topic: &'static str,
    pub counts: TapCounts,
    pub written: u64,
}

/// What a recorder run did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordingReport {
    pub end: RecordingEnd,
    pub files: Vec<PathBuf>,
    pub bytes_written: u64,
    pub topics: Vec<TopicReport>,
    /// Selected channels that never opened, with the last reason.
    pub unopened: Vec<(&'static str, String)>,
    pub removed_files: Vec<PathBuf>,
    /// How often the disk filled up (each time the open segment was finished and recording
    /// paused until there was room again).
    pub disk_full_events: u32,
}

impl RecordingReport {
    pub fn messages_written(&self) -> u64 {
        self.topics.iter().map(|topic| topic.written).sum()
    }

    pub fn total_dropped(&self) -> u64 {
        self.topics
            .iter()
            .map(|topic| topic.counts.dropped_by_transport + topic.counts.dropped_by_queue)
            .sum()
    }
}

impl std::fmt::Display for RecordingReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "recording ended ({:?}): {} message(s), {} in {} file(s)",
            self.end,
            self.messages_written(),
            format_bytes(self.bytes_written),
            self.files.len()
        )?;
        for file in &self.files {
            writeln!(f, "  {}", file.display())?;
        }
        writeln!(
            f,
            "  {:<24} {:>10} {:>10} {:>16} {:>14}",
            "topic", "received", "written", "dropped(buffer)", "dropped(queue)"
        )?;
        for topic in &self.topics {
            writeln!(
                f,
                "  {:<24} {:>10} {:>10} {:>16} {:>14}",
                topic.topic,
                topic.counts.received,
                topic.written,
                topic.counts.dropped_by_transport,
                topic.counts.dropped_by_queue
            )?;
        }
        for (topic, reason) in &self.unopened {
            writeln!(f, "  not recorded: {topic}: {reason}")?;
        }
        if self.disk_full_events > 0 {
            writeln!(
                f,
                "  the disk was full {} time(s): recording paused, messages dropped(queue)",
                self.disk_full_events
            )?;
        }
        Ok(())
    }
}

/// The recorder could not run.
#[derive(Debug, thiserror::Error)]
pub enum RecorderError {
    /// An option has an unusable value.
    #[error("recorder option {option} {value:?}: {reason}")]
    InvalidOption {
        option: &'static str,
        value: String,
        reason: String,
    },
    /// The include/exclude patterns and layers leave no channel to record.
    #[error(
        "no catalogue channel matches the topic selection (include {include:?}, exclude {exclude:?}, layers {layers:?})"
    )]
    NothingSelected {
        include: Vec<String>,
        exclude: Vec<String>,
        layers: Vec<&'static str>,
    },
    #[error(transparent)]
    Node(#[from] harvest_ipc::error::NodeError),
    /// The heartbeat publisher cannot be opened.
    #[error("heartbeats: {0}")]
    Health(#[from] harvest_ipc::error::OpenChannelError),
    /// The wait set failed.
    #[error("recorder event loop: {0}")]
    Wait(String),
    #[error(transparent)]
    Write(#[from] WriteError),
}

/// Runs the recorder process until SIGINT/SIGTERM (what `harvest recorder` calls).
pub fn run_recorder(
    args: &RecorderArgs,
    domain: &Domain,
    process_name: &str,
) -> Result<RecordingReport, RecorderError> {
    run_recorder_until(args, domain, process_name, &RecorderControl::default())
}

/// Runs the recorder until SIGINT/SIGTERM or until `control.stop` is set.
pub fn run_recorder_until(
    args: &RecorderArgs,
    domain: &Domain,
    process_name: &str,
    control: &RecorderControl,
) -> Result<RecordingReport, RecorderError> {
    let settings = args.output_settings(domain)?;
    let filter = args.topic_filter();
    let all_topics = catalogue_topics();
    let topic_names: Vec<&str> = all_topics.iter().map(|topic| topic.spec.topic).collect();
    for pattern in filter.unmatched_includes(&topic_names) {
        tracing::warn!(pattern, "--include pattern matches no catalogue channel");
    }
    let topics: Vec<TopicInfo> = all_topics
        .into_iter()
        .filter(|topic| filter.selects(topic.spec.topic, topic.spec.layer))
        .collect();
    if topics.is_empty() {
        return Err(RecorderError::NothingSelected {
            include: filter.include.clone(),
            exclude: filter.exclude.clone(),
            layers: filter
                .layers
                .iter()
                .map(|layer| layer_name(*layer))
                .collect(),
        });
    }
    let context = Context::new(domain, process_name)?;
    let mut health = HealthReporter::new(&context)?;
    let started = ClockPair::now();
    let recording_fields =
        recording_fields(args, &settings, domain, process_name, &topics, started);
    // The events channel first, then the camera's video and depth, then the mapped channels.
    let events_index = topics.len();
    let mut foreign = vec![events_channel()];
    let camera_index = topics
        .iter()
        .position(|topic| topic.spec.topic == catalogue::CAMERA_RGBD.spec.topic);
    let video = match (args.video_settings()?, camera_index) {
        (Some(settings), Some(camera)) => {
            let channels = VideoChannels {
                camera,
                video: topics.len() + foreign.len(),
                depth: topics.len() + foreign.len() + 1,
            };
            foreign.extend([video_channel(), depth_channel()]);
            Some((settings, channels))
        }
        _ => None,
    };
    let mapped_index = topics.len() + foreign.len();
    if !args.no_foxglove {
        foreign.extend(view_thread::foreign_channels());
    }
    let flight_settings = args.flight_settings(&topics);
    let mut writer = WriterHandle::spawn(
        settings,
        topics.clone(),
        foreign,
        recording_fields.clone(),
        session_records(args),
        started,
    )?;
    if !args.no_foxglove {
        let view = ViewFeed::spawn(
            &topics,
            mapped_index,
            view_mounting(args),
            writer.enqueuer(),
            started,
        )
        .map_err(|error| RecorderError::Wait(format!("cannot start the view thread: {error}")))?;
        writer.attach_view(view);
    }
    if let Some((settings, channels)) = video {
        let feed =
            VideoFeed::spawn(settings, channels, writer.enqueuer(), started).map_err(|error| {
                RecorderError::Wait(format!("cannot start the camera video: {error}"))
            })?;
        writer.attach_video(feed);
    }
    if let Some(flight_settings) = flight_settings {
        let flight = FlightFeed::spawn(
            flight_settings,
            topics.clone(),
            recording_fields,
            session_records(args),
            started,
            log_time_offset_ns(started),
            LiveEvents {
                enqueuer: writer.enqueuer(),
                index: events_index,
            },
        )
        .map_err(|error| {
            RecorderError::Wait(format!("cannot start the flight recorder: {error}"))
        })?;
        writer.attach_flight(flight);
    }
    let waiter = Waiter::new().map_err(|error| RecorderError::Wait(error.to_string()))?;

    let mut taps: Vec<Box<dyn Tap>> = Vec::new();
    let mut pending: Vec<usize> = (0..topics.len()).collect();
    let mut last_failure: BTreeMap<usize, String> = BTreeMap::new();
    let mut heartbeat = Heartbeat::new(control.housekeeping_period);
    let end = loop {
        open_pending(
            &context,
            &topics,
            &mut pending,
            &mut taps,
            &mut last_failure,
            &writer,
        );
        if pending.is_empty() {
            control.ready.store(true, Ordering::SeqCst);
        }
        heartbeat.send(&mut health, &taps, &writer, true);
        match run_attached(
            &waiter,
            &taps,
            &mut writer,
            &mut health,
            &mut heartbeat,
            control,
            args.retry_interval,
            !pending.is_empty(),
        )? {
            LoopEnd::Reopen => continue,
            LoopEnd::Signal => break RecordingEnd::Signal,
            LoopEnd::Stopped | LoopEnd::WriterFailed => break RecordingEnd::Stopped,
        }
    };
    // Drain what is still queued in the subscribers, then close the file.
    if !writer.has_failed() {
        for tap in &taps {
            if let Err(error) = tap.drain(&mut writer) {
                tracing::warn!(topic = tap.topic(), %error, "final drain failed");
            }
        }
    }
    let unopened: Vec<(&'static str, String)> = pending
        .iter()
        .map(|&index| {
            (
                topics[index].spec.topic,
                last_failure.get(&index).cloned().unwrap_or_default(),
            )
        })
        .collect();
    if let Some(flight) = writer.finish_flight() {
        tracing::info!(
            ring_capacity_bytes = flight.ring_capacity_bytes,
            appended = flight.ring.appended,
            left_out_behind = flight.dropped_behind,
            left_out_held = flight.ring.dropped_held,
            left_out_too_large = flight.ring.dropped_too_large,
            triggers = flight.triggers,
            clips = flight.clips.clips.len(),
            clips_failed = flight.clips.failed,
            clips_removed = flight.clips.removed,
            clip_max_latency_s = flight.clips.max_latency_s,
            "flight recorder"
        );
    }
    let video_report = writer.finish_video();
    if let Some(video) = &video_report {
        tracing::info!(
            admitted = video.admitted,
            encoded = video.encoded,
            keyframes = video.keyframes,
            depth = video.depth_encoded,
            dropped_behind = video.dropped_behind,
            dropped_by_queue = video.dropped_by_queue,
            failed = video.failed,
            encode_ms_mean = video.encode_ms_mean(),
            encode_ms_max = video.encode_ms_max,
            video_bytes = video.video_bytes,
            depth_bytes = video.depth_bytes,
            "camera video"
        );
    }
    if let Some(view) = writer.finish_view() {
        tracing::info!(
            admitted = view.admitted,
            written = view.written,
            dropped_behind = view.dropped_behind,
            dropped_by_queue = view.dropped_by_queue,
            failed = view.failed,
            "mapped Foxglove channels"
        );
    }
    let mut drops = drops_record(&taps, &unopened);
    if let Some(video) = &video_report {
        drops.metadata.extend(video_drop_entries(video));
    }
    let _ = health.report(
        ProcessRunState::Stopping,
        heartbeat.received(&taps),
        "dropped",
        total_drops(&taps),
    );
    let written = writer.finish(vec![drops])?;
    let mut topic_reports: Vec<TopicReport> = taps
        .iter()
        .map(|tap| {
            let mut counts = tap.counts();
            // Messages already queued when the disk filled up were dropped by the writer.
            counts.dropped_by_queue += written
                .dropped_disk_full_per_topic
                .get(tap.topic_index())
                .copied()
                .unwrap_or(0);
            TopicReport {
                topic: tap.topic(),
                counts,
                written: written
                    .messages_per_topic
                    .get(tap.topic_index())
                    .copied()
                    .unwrap_or(0),
            }
        })
        .collect();
    topic_reports.sort_by_key(|report| report.topic);
    let report = RecordingReport {
        end,
        files: written.files,
        bytes_written: written.bytes_written,
        topics: topic_reports,
        unopened,
        removed_files: written.removed_files,
        disk_full_events: written.disk_full_events,
    };
    for topic in &report.topics {
        let dropped = topic.counts.dropped_by_transport + topic.counts.dropped_by_queue;
        if dropped > 0 {
            tracing::warn!(
                topic = topic.topic,
                dropped_by_buffer = topic.counts.dropped_by_transport,
                dropped_by_queue = topic.counts.dropped_by_queue,
                received = topic.counts.received,
                "messages were lost"
            );
        }
    }
    tracing::info!("{report}");
    Ok(report)
}

enum LoopEnd {
    Signal,
    Stopped,
    WriterFailed,
    /// Leave the wait set to open channels that became available.
    Reopen,
}

#[allow(clippy::too_many_arguments)]
fn run_attached(
    waiter: &Waiter,
    taps: &[Box<dyn Tap>],
    writer: &mut WriterHandle,
    health: &mut HealthReporter,
    heartbeat: &mut Heartbeat,
    control: &RecorderControl,
    retry_interval: Duration,
    retry_pending: bool,
) -> Result<LoopEnd, RecorderError> {
    let tick = waiter
        .waitset()
        .attach_interval(control.housekeeping_period)
        .map_err(|error| RecorderError::Wait(format!("attach interval: {error:?}")))?;
    let guards = taps
        .iter()
        .map(|tap| tap.attach(waiter))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|error| RecorderError::Wait(format!("attach listener: {error}")))?;
    let retry_at = Instant::now() + retry_interval;
    let mut warned = vec![false; taps.len()];
    let mut end = LoopEnd::Stopped;
    let result = waiter.run(|attachment| -> Result<Flow, RecorderError> {
        for (index, (tap, guard)) in taps.iter().zip(&guards).enumerate() {
            if attachment.has_event_from(guard)
                && let Err(error) = tap.drain(writer)
                && !std::mem::replace(&mut warned[index], true)
            {
                tracing::warn!(topic = tap.topic(), %error, "receive failed");
            }
        }
        if attachment.has_event_from(&tick) {
            heartbeat.send(health, taps, writer, false);
            if control.stop.load(Ordering::SeqCst) {
                end = LoopEnd::Stopped;
                return Ok(Flow::Stop);
            }
            if writer.has_failed() {
                end = LoopEnd::WriterFailed;
                return Ok(Flow::Stop);
            }
            if retry_pending && Instant::now() >= retry_at {
                end = LoopEnd::Reopen;
                return Ok(Flow::Stop);
            }
        }
        Ok(Flow::Continue)
    });
    match result {
        Ok(RunEnd::Signal) => Ok(LoopEnd::Signal),
        Ok(RunEnd::Stopped) => Ok(end),
        Err(RunError::Wait(error)) => Err(RecorderError::Wait(error.to_string())),
        Err(RunError::Callback(error)) => Err(error),
    }
}

/// Opens taps for the pending topics that can be opened now.
fn open_pending(
    context: &Context,
    topics: &[TopicInfo],
    pending: &mut Vec<usize>,
    taps: &mut Vec<Box<dyn Tap>>,
    last_failure: &mut BTreeMap<usize, String>,
    writer: &WriterHandle,
) {
    struct Opener<'a> {
        context: &'a Context,
        topics: &'a [TopicInfo],
        pending: &'a mut Vec<usize>,
        opened: Vec<Box<dyn Tap>>,
        failures: Vec<(usize, String)>,
    }
    impl ChannelVisitor for Opener<'_> {
        fn visit<T: Payload>(&mut self, channel: Channel<T>) {
            let topics = self.topics;
            let Some(position) = self
                .pending
                .iter()
                .position(|&index| topics[index].spec.topic == channel.spec.topic)
            else {
                return;
            };
            let index = self.pending[position];
            match TypedTap::open(self.context, channel, index) {
                Ok(tap) => {
                    self.pending.remove(position);
                    self.opened.push(Box::new(tap));
                }
                Err(error) => self.failures.push((index, error.to_string())),
            }
        }
    }
    let mut opener = Opener {
        context,
        topics,
        pending,
        opened: Vec::new(),
        failures: Vec::new(),
    };
    catalogue::visit_all(&mut opener);
    for tap in &opener.opened {
        tracing::debug!(topic = tap.topic(), "tapped");
        writer.add_channel(tap.topic_index());
        last_failure.remove(&tap.topic_index());
    }
    for (index, reason) in opener.failures {
        let topic = topics[index].spec.topic;
        if last_failure.get(&index) != Some(&reason) {
            tracing::warn!(topic, %reason, "cannot tap channel yet; retrying");
        }
        last_failure.insert(index, reason);
    }
    taps.extend(opener.opened);
}

/// The heartbeat's detail while the disk is full (with the dropped count as its value): the
/// supervisor's status line shows it.
pub const DISK_FULL_DETAIL: &str = "DISK FULL, paused; dropped";

/// Heartbeats at `HEARTBEAT_PERIOD`, driven by the housekeeping tick.
struct Heartbeat {
    last: Option<Instant>,
    min_gap: Duration,
    drops_at_last: u64,
}

impl Heartbeat {
    fn new(housekeeping_period: Duration) -> Self {
        Self {
            last: None,
            min_gap: HEARTBEAT_PERIOD.saturating_sub(housekeeping_period / 2),
            drops_at_last: 0,
        }
    }

    fn received(&self, taps: &[Box<dyn Tap>]) -> u64 {
        taps.iter().map(|tap| tap.counts().received).sum()
    }

    fn send(
        &mut self,
        health: &mut HealthReporter,
        taps: &[Box<dyn Tap>],
        writer: &WriterHandle,
        force: bool,
    ) {
        if !force && self.last.is_some_and(|last| last.elapsed() < self.min_gap) {
            return;
        }
        self.last = Some(Instant::now());
        let drops = total_drops(taps);
        if drops > self.drops_at_last {
            // Which topic lost messages, and where: the subscriber's buffer (the tap fell
            // behind) or the writer's queue (the disk fell behind).
            let per_topic: Vec<String> = taps
                .iter()
                .filter_map(|tap| {
                    let counts = tap.counts();
                    (counts.dropped_by_transport + counts.dropped_by_queue > 0).then(|| {
                        format!(
                            "{} buffer {} queue {}",
                            tap.topic(),
                            counts.dropped_by_transport,
                            counts.dropped_by_queue
                        )
                    })
                })
                .collect();
            tracing::warn!(
                dropped = drops,
                new = drops - self.drops_at_last,
                topics = %per_topic.join(", "),
                "messages lost"
            );
        }
        let disk_full = writer.is_disk_full();
        let state = if writer.has_failed() || disk_full || drops > self.drops_at_last {
            ProcessRunState::Degraded
        } else {
            ProcessRunState::Running
        };
        self.drops_at_last = drops;
        let detail = if disk_full {
            DISK_FULL_DETAIL
        } else {
            "dropped"
        };
        if let Err(error) = health.report(state, self.received(taps), detail, drops) {
            tracing::debug!(%error, "heartbeat not sent");
        }
    }
}

fn total_drops(taps: &[Box<dyn Tap>]) -> u64 {
    taps.iter()
        .map(|tap| {
            let counts = tap.counts();
            counts.dropped_by_transport + counts.dropped_by_queue
        })
        .sum()
}

fn drops_record(
    taps: &[Box<dyn Tap>],
    unopened: &[(&'static str, String)],
) -> mcap::records::Metadata {
    let mut entries = BTreeMap::new();
    for tap in taps {
        let counts = tap.counts();
        let topic = tap.topic();
        entries.insert(format!("{topic}.received"), counts.received.to_string());
        entries.insert(
            format!("{topic}.dropped_buffer"),
            counts.dropped_by_transport.to_string(),
        );
        entries.insert(
            format!("{topic}.dropped_queue"),
            counts.dropped_by_queue.to_string(),
        );
        entries.insert(
            format!("{topic}.encode_failures"),
            counts.encode_failures.to_string(),
        );
    }
    for (topic, reason) in unopened {
        entries.insert(format!("{topic}.not_recorded"), reason.clone());
    }
    mcap::records::Metadata {
        name: metadata::DROPS.to_owned(),
        metadata: entries,
    }
}

/// The camera video's counts in the `harvest.drops` record.
fn video_drop_entries(video: &VideoReport) -> BTreeMap<String, String> {
    BTreeMap::from([
        (
            format!("{VIDEO_TOPIC}.admitted"),
            video.admitted.to_string(),
        ),
        (format!("{VIDEO_TOPIC}.encoded"), video.encoded.to_string()),
        (
            format!("{VIDEO_TOPIC}.keyframes"),
            video.keyframes.to_string(),
        ),
        (
            format!("{VIDEO_TOPIC}.dropped_behind"),
            video.dropped_behind.to_string(),
        ),
        (
            format!("{VIDEO_TOPIC}.dropped_queue"),
            video.dropped_by_queue.to_string(),
        ),
        (format!("{VIDEO_TOPIC}.failed"), video.failed.to_string()),
        (
            format!("{VIDEO_TOPIC}.encode_ms_mean"),
            format!("{:.2}", video.encode_ms_mean()),
        ),
        (
            format!("{VIDEO_TOPIC}.encode_ms_max"),
            format!("{:.2}", video.encode_ms_max),
        ),
        (
            format!("{DEPTH_TOPIC}.encoded"),
            video.depth_encoded.to_string(),
        ),
    ])
}

fn recording_fields(
    args: &RecorderArgs,
    settings: &OutputSettings,
    domain: &Domain,
    process_name: &str,
    topics: &[TopicInfo],
    started: ClockPair,
) -> BTreeMap<String, String> {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|name| name.trim().to_owned())
        .unwrap_or_default();
    let topic_list: Vec<&str> = topics.iter().map(|topic| topic.spec.topic).collect();
    let layers: Vec<&str> = args
        .layers
        .iter()
        .map(|layer| layer_name(layer.layer()))
        .collect();
    BTreeMap::from([
        (
            "software_version".to_owned(),
            metadata::SOFTWARE_VERSION.to_owned(),
        ),
        ("recorder".to_owned(), process_name.to_owned()),
        ("domain".to_owned(), domain.name().to_owned()),
        ("host".to_owned(), host),
        (
            "session_started_utc".to_owned(),
            format_utc_iso(started.realtime_ns),
        ),
        (
            "message_encoding".to_owned(),
            harvest_ipc::codec::ENCODING.to_owned(),
        ),
        (
            "compression".to_owned(),
            settings.chunks.compression.name().to_owned(),
        ),
        (
            "compression_level".to_owned(),
            settings.chunks.compression_level.to_string(),
        ),
        (
            "chunk_size_bytes".to_owned(),
            settings.chunks.chunk_size_bytes.to_string(),
        ),
        (
            "chunk_interval_ms".to_owned(),
            settings.chunk_interval.as_millis().to_string(),
        ),
        (
            "camera".to_owned(),
            match args.camera {
                CameraRecord::Video => format!(
                    "video: {VIDEO_TOPIC} H.264 at {} Hz, {} bit/s; {DEPTH_TOPIC} at {} Hz",
                    args.video_rate, args.video_bitrate, args.depth_rate
                ),
                CameraRecord::Raw => "raw".to_owned(),
            },
        ),
        ("include".to_owned(), args.include.join(",")),
        ("exclude".to_owned(), args.exclude.join(",")),
        ("layers".to_owned(), layers.join(",")),
        ("topics".to_owned(), topic_list.join(",")),
        (
            "log_time".to_owned(),
            "receive time, Unix-epoch ns: CLOCK_MONOTONIC + log_time_offset_ns of harvest.clock"
                .to_owned(),
        ),
        (
            "publish_time".to_owned(),
            "header.publish_ns + log_time_offset_ns of harvest.clock, Unix-epoch ns".to_owned(),
        ),
    ])
}

/// The sensor mountings for the mapped 3D view; a file that cannot be used leaves its sensor
/// out of the view (with a warning), it never stops the recording.
fn view_mounting(args: &RecorderArgs) -> Mounting {
    let robot_from_camera = args.calibration.as_deref().and_then(|path| {
        robot_from_camera_file(path)
            .inspect_err(
                |error| tracing::warn!(%error, "the mapped view leaves the camera unplaced"),
            )
            .ok()
    });
    let camera_from_lidar = args.lidar_extrinsic.as_deref().and_then(|path| {
        camera_from_lidar_file(path)
            .inspect_err(
                |error| tracing::warn!(%error, "the mapped view leaves the LiDAR unplaced"),
            )
            .ok()
    });
    Mounting {
        robot_from_camera,
        camera_from_lidar,
    }
}

fn session_records(args: &RecorderArgs) -> Vec<mcap::records::Metadata> {
    let mut records = Vec::new();
    if let Some(path) = &args.launch_file {
        records.push(metadata::file_record(metadata::LAUNCH, path));
    }
    if let Some(path) = &args.calibration {
        records.push(metadata::file_record(metadata::CALIBRATION, path));
    }
    if let Some(scenario) = &args.scenario {
        records.push(metadata::scenario_record(scenario));
    }
    if !args.notes.is_empty() {
        records.push(metadata::notes_record(&args.notes));
    }
    records
}
