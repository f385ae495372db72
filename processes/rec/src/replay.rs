//! `harvest replay FILE...`: republishes recorded messages into a domain's channels at their
//! recorded timing (or scaled by `--rate`, or as fast as possible with `--fast`).
//!
//! Each message is decoded with `Payload::decode_into` straight into a sample loaned from the
//! channel's shared memory (frames never pass through the stack) and sent; the transport
//! stamps a fresh `msg_seq` and `publish_ns`, `capture_ns` and the payload are the recorded
//! ones. The replay clock sleeps until each message's due time: `wall_start + (log_time -
//! first_log_time) / rate`, shifted by the time spent paused.
//!
//! With `--ros2 --map MAP.toml` the files are a ROS 2 bag (a rosbag2 directory or its MCAP
//! files), mapped into the stack's channels by [`crate::ros2_input`] at the same timing.
//!
//! Heartbeats (`system/health`) are not replayed unless `--with-health` is given: recorded
//! heartbeats would make a live supervisor believe long-gone processes are alive.

use crate::keyboard::{Key, Keyboard};
use crate::ros2_input::{Ros2Input, Ros2InputError, bag_files, check_bag_topics, read_map};
use crate::video_replay::{CameraOutcome, CameraReplay};
use harvest_ipc::catalogue::{self, CAMERA_RGBD, PROCESS_HEALTH};
use harvest_ipc::{Channel, ChannelVisitor, Context, Domain, Payload, Publisher};
use harvest_recording::camera_record::{DEPTH_TOPIC, VIDEO_TOPIC};
use harvest_recording::foxglove_export::FoxgloveWriter;
use harvest_recording::recorded_events::EVENTS_TOPIC;
use harvest_recording::recording_file::ReadError;
use harvest_recording::scan::{ScanEnd, ScanItem, ScanOptions, scan_file};
use harvest_recording::schema::schema_name;
use harvest_recording::time_base::FileTimeBase;
use harvest_recording::time_window::{absolute_window, recording_start_ns};
use harvest_recording::topic_filter::TopicFilter;
use harvest_recording::units::parse_duration;
use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Options of `harvest replay`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReplayArgs {
    /// Recording file(s); segments of one recording are replayed in the order given.
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Playback speed relative to the recording (2 = twice as fast).
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// Start over at the end until interrupted.
    #[arg(long = "loop")]
    pub loop_playback: bool,
    /// Skip this much of the recording's beginning (e.g. 12.5s).
    #[arg(long, value_parser = parse_duration)]
    pub start_offset: Option<Duration>,
    /// Replay only this much of the recording.
    #[arg(long, value_parser = parse_duration)]
    pub duration: Option<Duration>,
    /// Replay only topics matching one of these globs; repeatable.
    #[arg(long = "include", value_name = "GLOB")]
    pub include: Vec<String>,
    /// Leave out topics matching one of these globs; repeatable.
    #[arg(long = "exclude", value_name = "GLOB")]
    pub exclude: Vec<String>,
    /// Publish as fast as possible, ignoring the recorded timing.
    #[arg(long)]
    pub fast: bool,
    /// Also replay recorded heartbeats (`system/health`).
    #[arg(long)]
    pub with_health: bool,
    /// Do not read keys from the terminal (space: pause, s: step, q: quit).
    #[arg(long)]
    pub no_keyboard: bool,
    /// After the last message, keep the channels open this long so subscribers can still take
    /// what they have not read (a sample is gone once its publisher closes).
    #[arg(long, default_value = "500ms", value_parser = parse_duration)]
    pub linger: Duration,
    /// FILE is a ROS 2 bag (a rosbag2 directory, MCAP storage, or its .mcap file), mapped into
    /// the stack's channels as `--map` says.
    #[arg(long, requires = "map")]
    pub ros2: bool,
    /// The map of a ROS 2 bag's topics onto the stack's channels (docs/ros2/map.example.toml).
    #[arg(long, value_name = "MAP.toml", requires = "ros2")]
    pub map: Option<PathBuf>,
}

impl ReplayArgs {
    /// Replays `files` once at recorded speed, every topic but heartbeats, no keyboard.
    pub fn for_files(files: Vec<PathBuf>) -> Self {
        Self {
            files,
            rate: 1.0,
            loop_playback: false,
            start_offset: None,
            duration: None,
            include: Vec::new(),
            exclude: Vec::new(),
            fast: false,
            with_health: false,
            no_keyboard: true,
            linger: Duration::from_millis(500),
            ros2: false,
            map: None,
        }
    }
}

/// How a replay ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplayEnd {
    /// Every selected message was published.
    Finished,
    /// `q` was pressed.
    Quit,
    /// SIGINT or SIGTERM.
    Signal,
}

/// What a replay did.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayReport {
    pub end: ReplayEnd,
    /// Messages published per topic (over all loops).
    pub published: BTreeMap<String, u64>,
    /// Topics not replayed: messages skipped and why.
    pub skipped: BTreeMap<String, (u64, String)>,
    /// Messages of the channels mapped for Foxglove (protobuf views of the raw channels, made
    /// again by whoever views them), not replayed.
    pub mapped_views: u64,
    /// Messages of the recorder's events channel (triggers and marks found in the replayed
    /// channels themselves), not replayed.
    pub recorded_events: u64,
    /// `camera/rgbd` frames made from the continuous record's video and depth (also counted
    /// in `published` under `camera/rgbd`).
    pub frames_from_video: u64,
    /// Video messages that made no frame, by reason (entered before an IDR, no depth yet).
    pub video_waiting: BTreeMap<String, u64>,
    pub loops: u32,
    /// Recorded time covered by the published messages (one pass), ns.
    pub recorded_span_ns: u64,
    /// Wall time spent publishing, paused time excluded.
    pub wall_time: Duration,
    /// Files that could not be read to their end, with the reason.
    pub incomplete: Vec<(PathBuf, String)>,
    /// A ROS 2 bag's replay: frames assembled (and images dropped), clouds published.
    pub ros2: Option<Ros2Summary>,
}

/// What a ROS 2 bag's replay published on the stack's channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ros2Summary {
    pub frames: harvest_ros2_mapping::frame_assembler::AssemblyCounts,
    pub clouds: u64,
}

impl ReplayReport {
    pub fn messages(&self) -> u64 {
        self.published.values().sum()
    }

    /// Recorded time replayed per second of wall time.
    pub fn speed_factor(&self) -> f64 {
        let wall_s = self.wall_time.as_secs_f64();
        if wall_s > 0.0 {
            self.recorded_span_ns as f64 * 1e-9 * f64::from(self.loops.max(1)) / wall_s
        } else {
            0.0
        }
    }
}

impl std::fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "replay {:?}: {} message(s), {:.3} s recorded in {:.3} s wall ({:.2}x real time), {} loop(s)",
            self.end,
            self.messages(),
            self.recorded_span_ns as f64 * 1e-9,
            self.wall_time.as_secs_f64(),
            self.speed_factor(),
            self.loops
        )?;
        for (topic, count) in &self.published {
            writeln!(f, "  {topic:<24} {count:>10}")?;
        }
        for (topic, (count, reason)) in &self.skipped {
            writeln!(f, "  skipped {topic}: {count} message(s): {reason}")?;
        }
        if self.mapped_views > 0 {
            writeln!(
                f,
                "  {} message(s) of the mapped Foxglove channels left out",
                self.mapped_views
            )?;
        }
        if self.recorded_events > 0 {
            writeln!(
                f,
                "  {} message(s) of the recorder's events channel left out",
                self.recorded_events
            )?;
        }
        if self.frames_from_video > 0 {
            writeln!(
                f,
                "  {} camera/rgbd frame(s) decoded from {VIDEO_TOPIC} with {DEPTH_TOPIC}",
                self.frames_from_video
            )?;
        }
        for (reason, count) in &self.video_waiting {
            writeln!(f, "  {count} video frame(s) gave no frame: {reason}")?;
        }
        for (file, reason) in &self.incomplete {
            writeln!(f, "  {}: {reason}", file.display())?;
        }
        if let Some(ros2) = &self.ros2 {
            let counts = &ros2.frames;
            writeln!(
                f,
                "  ROS 2 bag: {} camera frame(s) and {} cloud(s) published; unpaired {} colour, {} depth image(s); {} pair(s) before the camera models",
                counts.frames,
                ros2.clouds,
                counts.unpaired_color,
                counts.unpaired_depth,
                counts.before_camera_info
            )?;
        }
        Ok(())
    }
}

/// The replay could not run.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// `--rate` is not a positive number.
    #[error("--rate {0}: must be a positive number")]
    InvalidRate(f64),
    #[error(transparent)]
    Read(#[from] ReadError),
    #[error(transparent)]
    Node(#[from] harvest_ipc::error::NodeError),
    /// The terminal could not be set up for keyboard control.
    #[error("keyboard control: {0} (use --no-keyboard)")]
    Terminal(String),
    /// The SIGINT/SIGTERM handler could not be installed.
    #[error("installing the signal handler: {0}")]
    Signal(std::io::Error),
    /// A ROS 2 bag or its map cannot be used, or one of its messages is refused.
    #[error("ROS 2 bag: {0}")]
    Ros2(String),
}

impl From<Ros2InputError> for ReplayError {
    fn from(error: Ros2InputError) -> Self {
        Self::Ros2(error.to_string())
    }
}

/// A publisher that takes encoded messages of one payload type.
trait ReplayPort {
    /// Decodes `bytes` into a loaned sample and sends it.
    fn publish(&mut self, bytes: &[u8]) -> Result<(), String>;
}

struct TypedPort<T: Payload> {
    publisher: Publisher<T>,
}

impl<T: Payload> ReplayPort for TypedPort<T> {
    fn publish(&mut self, bytes: &[u8]) -> Result<(), String> {
        let mut loan = self.publisher.loan().map_err(|error| error.to_string())?;
        T::decode_into(bytes, &mut loan)
            .map_err(|error| format!("undecodable message: {error}"))?;
        self.publisher
            .send(loan)
            .map(|_| ())
            .map_err(|error| error.to_string())
    }
}

/// Opens the publisher for a recorded channel, if this build's catalogue has the same topic
/// with the same payload type and version.
fn open_port(context: &Context, topic: &str, schema: &str) -> Result<Box<dyn ReplayPort>, String> {
    struct Find<'a> {
        context: &'a Context,
        topic: &'a str,
        schema: &'a str,
        result: Option<Result<Box<dyn ReplayPort>, String>>,
    }
    impl ChannelVisitor for Find<'_> {
        fn visit<T: Payload>(&mut self, channel: Channel<T>) {
            if channel.spec.topic != self.topic {
                return;
            }
            let current = schema_name(T::TYPE_NAME, T::VERSION);
            self.result = Some(if current != self.schema {
                Err(format!(
                    "recorded as {:?}, this build's channel carries {current}",
                    self.schema
                ))
            } else {
                self.context
                    .publisher(channel)
                    .map(|publisher| Box::new(TypedPort { publisher }) as Box<dyn ReplayPort>)
                    .map_err(|error| error.to_string())
            });
        }
    }
    let mut find = Find {
        context,
        topic,
        schema,
        result: None,
    };
    catalogue::visit_all(&mut find);
    find.result
        .unwrap_or_else(|| Err("not a channel of this build's catalogue".to_owned()))
}

/// Runs `harvest replay` into `domain`; after the last message the channels stay open for
/// `args.linger`.
pub fn run_replay(args: &ReplayArgs, domain: &Domain) -> Result<ReplayReport, ReplayError> {
    run_replay_with(args, domain, |_| std::thread::sleep(args.linger))
}

/// Runs a replay into `domain` and calls `before_close` with the report once publishing is
/// over (not after a signal), while the channels are still open.
pub fn run_replay_with(
    args: &ReplayArgs,
    domain: &Domain,
    before_close: impl FnOnce(&ReplayReport),
) -> Result<ReplayReport, ReplayError> {
    if !(args.rate.is_finite() && args.rate > 0.0) {
        return Err(ReplayError::InvalidRate(args.rate));
    }
    harvest_ipc::termination::install_handler().map_err(ReplayError::Signal)?;
    let mut exclude = args.exclude.clone();
    if !args.with_health {
        exclude.push(PROCESS_HEALTH.spec.topic.to_owned());
    }
    let filter = TopicFilter::patterns(&args.include, &exclude);
    let files = if args.ros2 {
        bag_files(&args.files).map_err(ReplayError::Ros2)?
    } else {
        args.files.clone()
    };
    let map = match (&args.map, args.ros2) {
        (Some(path), true) => {
            let map = read_map(path).map_err(ReplayError::Ros2)?;
            check_bag_topics(&map, &files).map_err(ReplayError::Ros2)?;
            Some(map)
        }
        _ => None,
    };
    let start_ns = match files.first() {
        Some(first) => recording_start_ns(first)?.unwrap_or(0),
        None => 0,
    };
    let end_offset = args
        .duration
        .map(|duration| args.start_offset.unwrap_or_default() + duration);
    let (from_ns, to_ns) = absolute_window(start_ns, args.start_offset, end_offset);
    let context = Context::new(domain, "replay")?;
    let mut ros2 = match map {
        Some(map) => Some(
            Ros2Input::open(map, &context).map_err(|error| ReplayError::Ros2(error.to_string()))?,
        ),
        None => None,
    };
    let mut fatal: Option<ReplayError> = None;
    let keyboard = if args.no_keyboard {
        None
    } else {
        Keyboard::open_if_terminal().map_err(ReplayError::Terminal)?
    };
    if keyboard.is_some() {
        eprintln!("replay: space = pause/resume, s = step, q = quit");
    }
    let mut clock = ReplayClock::new(args.rate, args.fast, keyboard);
    let mut ports: BTreeMap<String, Option<Box<dyn ReplayPort>>> = BTreeMap::new();
    // The camera rebuilt from video and depth (opened at the first such message).
    let mut camera: Option<Result<CameraReplay, String>> = None;
    let mut report = ReplayReport {
        end: ReplayEnd::Finished,
        published: BTreeMap::new(),
        skipped: BTreeMap::new(),
        mapped_views: 0,
        recorded_events: 0,
        frames_from_video: 0,
        video_waiting: BTreeMap::new(),
        loops: 0,
        recorded_span_ns: 0,
        wall_time: Duration::ZERO,
        incomplete: Vec::new(),
        ros2: None,
    };
    'passes: loop {
        report.loops += 1;
        clock.restart();
        let mut first_ns: Option<u64> = None;
        let mut last_ns = 0;
        if let Some(Ok(camera)) = camera.as_mut()
            && let Err(reason) = camera.restart()
        {
            tracing::warn!(%reason, "cannot restart the video decoder");
        }
        for file in &files {
            let mut stop: Option<ReplayEnd> = None;
            let mut time_base = FileTimeBase::default();
            let outcome = scan_file(
                file,
                ScanOptions {
                    log_time_window: Some((from_ns, to_ns)),
                },
                |item| {
                    let message = match item {
                        ScanItem::Message(message) => message,
                        ScanItem::Metadata(record) => {
                            time_base.observe(record);
                            return ControlFlow::Continue(());
                        }
                        _ => return ControlFlow::Continue(()),
                    };
                    if message.log_time < from_ns || message.log_time > to_ns {
                        return ControlFlow::Continue(());
                    }
                    let topic = &message.channel.topic;
                    if !filter.matches_topic(topic) {
                        return ControlFlow::Continue(());
                    }
                    if FoxgloveWriter::is_mapped_output(topic, &message.channel.message_encoding) {
                        report.mapped_views += 1;
                        return ControlFlow::Continue(());
                    }
                    if topic == EVENTS_TOPIC {
                        report.recorded_events += 1;
                        return ControlFlow::Continue(());
                    }
                    if let Some(input) = ros2.as_mut() {
                        if !input.uses(topic) {
                            report
                                .skipped
                                .entry(topic.clone())
                                .or_insert_with(|| (0, "not in the map file".to_owned()))
                                .0 += 1;
                            return ControlFlow::Continue(());
                        }
                        let anchor = *first_ns.get_or_insert(message.log_time);
                        last_ns = message.log_time;
                        if let Some(end) = clock.wait_for(message.log_time.saturating_sub(anchor)) {
                            stop = Some(end);
                            return ControlFlow::Break(());
                        }
                        let type_name = message
                            .channel
                            .schema
                            .as_ref()
                            .map(|schema| schema.name.as_str())
                            .unwrap_or("");
                        return match input.handle(
                            topic,
                            type_name,
                            &message.channel.message_encoding,
                            message.data,
                        ) {
                            Ok(()) => {
                                *report.published.entry(topic.clone()).or_insert(0) += 1;
                                ControlFlow::Continue(())
                            }
                            Err(error) => {
                                fatal = Some(error.into());
                                ControlFlow::Break(())
                            }
                        };
                    }
                    if topic == VIDEO_TOPIC || topic == DEPTH_TOPIC {
                        // The camera's frames, as video and depth: replayed as camera/rgbd.
                        let rgbd = CAMERA_RGBD.spec.topic;
                        if !filter.matches_topic(rgbd) {
                            return ControlFlow::Continue(());
                        }
                        let camera =
                            match camera.get_or_insert_with(|| CameraReplay::open(&context)) {
                                Ok(camera) => camera,
                                Err(reason) => {
                                    let entry = report
                                        .skipped
                                        .entry(topic.clone())
                                        .or_insert_with(|| (0, reason.clone()));
                                    entry.0 += 1;
                                    return ControlFlow::Continue(());
                                }
                            };
                        let is_video = topic == VIDEO_TOPIC;
                        if is_video {
                            let anchor = *first_ns.get_or_insert(message.log_time);
                            last_ns = message.log_time;
                            if let Some(end) =
                                clock.wait_for(message.log_time.saturating_sub(anchor))
                            {
                                stop = Some(end);
                                return ControlFlow::Break(());
                            }
                        }
                        let outcome = if is_video {
                            camera.video(message.data, &time_base)
                        } else {
                            camera.depth(message.data)
                        };
                        match outcome {
                            Ok(CameraOutcome::Published) => {
                                report.frames_from_video += 1;
                                *report.published.entry(rgbd.to_owned()).or_insert(0) += 1;
                            }
                            Ok(CameraOutcome::DepthTaken) => {}
                            Ok(CameraOutcome::Waiting(reason)) => {
                                *report.video_waiting.entry(reason.to_owned()).or_insert(0) += 1;
                            }
                            Err(reason) => {
                                let entry = report
                                    .skipped
                                    .entry(topic.clone())
                                    .or_insert_with(|| (0, reason.clone()));
                                if entry.0 == 0 {
                                    tracing::warn!(topic = %topic, %reason, "message not replayed");
                                }
                                entry.0 += 1;
                            }
                        }
                        return ControlFlow::Continue(());
                    }
                    let port = ports.entry(topic.clone()).or_insert_with(|| {
                        let schema = message
                            .channel
                            .schema
                            .as_ref()
                            .map(|schema| schema.name.as_str())
                            .unwrap_or("");
                        match open_port(&context, topic, schema) {
                            Ok(port) => Some(port),
                            Err(reason) => {
                                tracing::warn!(topic = %topic, %reason, "not replayed");
                                report.skipped.insert(topic.clone(), (0, reason));
                                None
                            }
                        }
                    });
                    let Some(port) = port else {
                        if let Some((count, _)) = report.skipped.get_mut(topic) {
                            *count += 1;
                        }
                        return ControlFlow::Continue(());
                    };
                    let anchor = *first_ns.get_or_insert(message.log_time);
                    last_ns = message.log_time;
                    if let Some(end) = clock.wait_for(message.log_time.saturating_sub(anchor)) {
                        stop = Some(end);
                        return ControlFlow::Break(());
                    }
                    match port.publish(message.data) {
                        Ok(()) => *report.published.entry(topic.clone()).or_insert(0) += 1,
                        Err(reason) => {
                            let entry = report
                                .skipped
                                .entry(topic.clone())
                                .or_insert_with(|| (0, reason.clone()));
                            if entry.0 == 0 {
                                tracing::warn!(topic = %topic, %reason, "message not replayed");
                            }
                            entry.0 += 1;
                        }
                    }
                    ControlFlow::Continue(())
                },
            )?;
            if let Some(error) = fatal.take() {
                return Err(error);
            }
            if let ScanEnd::Truncated { reason, .. } = &outcome.end
                && report.loops == 1
            {
                tracing::warn!(file = %file.display(), %reason, "recording incomplete; replayed what it holds");
                report.incomplete.push((file.clone(), reason.clone()));
            }
            if let Some(end) = stop {
                report.end = end;
                break 'passes;
            }
        }
        report.recorded_span_ns = report.recorded_span_ns.max(
            first_ns
                .map(|first| last_ns.saturating_sub(first))
                .unwrap_or(0),
        );
        if !args.loop_playback || first_ns.is_none() {
            break;
        }
        if harvest_ipc::termination::requested() {
            report.end = ReplayEnd::Signal;
            break;
        }
    }
    report.wall_time = clock.active_time();
    report.ros2 = ros2.as_ref().map(|input| Ros2Summary {
        frames: input.frame_counts().unwrap_or_default(),
        clouds: input.clouds_published,
    });
    if report.end != ReplayEnd::Signal {
        before_close(&report);
    }
    tracing::info!("{report}");
    Ok(report)
}

/// The replay clock: when each message is due, pause/step/quit from the keyboard, signals.
struct ReplayClock {
    rate: f64,
    fast: bool,
    keyboard: Option<Keyboard>,
    /// Wall time at which recorded offset 0 is due (moves forward by the time spent paused).
    origin: Instant,
    paused_since: Option<Instant>,
    /// Paused time over all passes.
    paused_total: Duration,
    started: Instant,
}

/// Longest single sleep, so signals and keys are noticed promptly.
const MAX_SLEEP: Duration = Duration::from_millis(100);

impl ReplayClock {
    fn new(rate: f64, fast: bool, keyboard: Option<Keyboard>) -> Self {
        let now = Instant::now();
        Self {
            rate,
            fast,
            keyboard,
            origin: now,
            paused_since: None,
            paused_total: Duration::ZERO,
            started: now,
        }
    }

    fn restart(&mut self) {
        self.origin = Instant::now();
    }

    fn active_time(&self) -> Duration {
        self.started.elapsed().saturating_sub(self.paused_total)
    }

    fn pause(&mut self) {
        if self.paused_since.is_none() {
            self.paused_since = Some(Instant::now());
            eprintln!("replay: paused (space: resume, s: step, q: quit)");
        }
    }

    fn resume(&mut self) {
        if let Some(since) = self.paused_since.take() {
            let paused = since.elapsed();
            self.origin += paused;
            self.paused_total += paused;
            eprintln!("replay: resumed");
        }
    }

    /// Waits until the message at `offset_ns` (recorded time since the pass's first message) is
    /// due. `None`: publish it now; `Some(end)`: stop the replay.
    fn wait_for(&mut self, offset_ns: u64) -> Option<ReplayEnd> {
        let offset = Duration::try_from_secs_f64(offset_ns as f64 * 1e-9 / self.rate)
            .unwrap_or(Duration::MAX);
        loop {
            if harvest_ipc::termination::requested() {
                return Some(ReplayEnd::Signal);
            }
            if self.paused_since.is_some() {
                match self
                    .keyboard
                    .as_ref()
                    .and_then(|keyboard| keyboard.next_key(MAX_SLEEP))
                {
                    Some(Key::TogglePause) => self.resume(),
                    // Publish this one message, stay paused; its due time moves to now.
                    Some(Key::Step) => {
                        let now = Instant::now();
                        if let Some(since) = self.paused_since.as_mut() {
                            self.paused_total += now - *since;
                            *since = now;
                        }
                        self.origin = now.checked_sub(offset).unwrap_or(now);
                        return None;
                    }
                    Some(Key::Quit) => return Some(ReplayEnd::Quit),
                    None => {}
                }
                continue;
            }
            let now = Instant::now();
            // A due time beyond what Instant can hold (absurd stamps) waits in MAX_SLEEP steps.
            let wait = if self.fast {
                Duration::ZERO
            } else {
                match self.origin.checked_add(offset) {
                    Some(due) => due.saturating_duration_since(now),
                    None => MAX_SLEEP,
                }
            };
            let key = match &self.keyboard {
                Some(keyboard) if !wait.is_zero() => keyboard.next_key(wait.min(MAX_SLEEP)),
                Some(keyboard) => keyboard.next_key(Duration::ZERO),
                None => {
                    if wait.is_zero() {
                        return None;
                    }
                    std::thread::sleep(wait.min(MAX_SLEEP));
                    None
                }
            };
            match key {
                Some(Key::TogglePause) | Some(Key::Step) => self.pause(),
                Some(Key::Quit) => return Some(ReplayEnd::Quit),
                None if wait.is_zero() => return None,
                None => {}
            }
        }
    }
}
