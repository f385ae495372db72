//! The continuous record's camera: `camera/rgbd` frames become H.264 video (`camera/video`) at
//! the video rate and depth images (`camera/depth`, PNG) at a reduced rate, on a thread of
//! their own ([`harvest_recording::camera_record`] has the formats).
//!
//! The receiving thread offers each frame ([`VideoFeed::offer`]); what the video rate admits
//! goes to this thread over a bounded queue (two frames) as a shared handle on the buffer the
//! frame was encoded into, not a copy. When the encoder falls behind, admitted frames are
//! dropped and counted: receiving, the raw channels and the flight recorder never wait for it.
//! The depth of every `depth_every`-th video frame is kept and queued before that frame's video,
//! so replay finds each depth image with its colour image. Both carry the raw frame's receive
//! time as log time (on the stack clock; the writer shifts it like every log time).

use crate::shared_queue::{self, QueueReceiver, QueueSender, Weighed};
use crate::writer_thread::{Enqueuer, MessageBytes, QueuedMessage};
use harvest_foxglove_mapping::RateLimit;
use harvest_recording::camera_record::{
    encode_depth_message, encode_video_message, split_encoded_frame,
};
use harvest_recording::video_codec::{H264Encoder, VideoSettings};
use harvest_recording::wall_clock::ClockPair;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Encoded frame bytes that may wait for the encoder (two 6.8 MB frames).
const MAX_PENDING_BYTES: usize = 16 << 20;
const MAX_PENDING_FRAMES: usize = 4;

/// How the camera goes into the continuous record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VideoFeedSettings {
    pub video: VideoSettings,
    /// Keep the depth of every this-many-th video frame (1: every one).
    pub depth_every: u32,
}

/// Where the encoded messages go in the writer's table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VideoChannels {
    /// Catalogue index of `camera/rgbd`.
    pub camera: usize,
    pub video: usize,
    pub depth: usize,
}

/// What the video thread did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct VideoReport {
    /// Frames the video rate admitted.
    pub admitted: u64,
    /// Admitted frames dropped because the encoder was behind.
    pub dropped_behind: u64,
    /// Video frames encoded.
    pub encoded: u64,
    /// IDR frames among them.
    pub keyframes: u64,
    /// Depth images encoded.
    pub depth_encoded: u64,
    /// Encoded messages the writer queue had no room for.
    pub dropped_by_queue: u64,
    /// Frames that did not decode or encode.
    pub failed: u64,
    /// Bytes of video and of depth queued for the writer.
    pub video_bytes: u64,
    pub depth_bytes: u64,
    /// Time the encoder took per video frame (colour conversion included), ms.
    pub encode_ms_total: f64,
    pub encode_ms_max: f64,
}

impl VideoReport {
    pub fn encode_ms_mean(&self) -> f64 {
        if self.encoded == 0 {
            0.0
        } else {
            self.encode_ms_total / self.encoded as f64
        }
    }

    /// Frames admitted but not recorded as video.
    pub fn dropped(&self) -> u64 {
        self.dropped_behind + self.dropped_by_queue + self.failed
    }
}

struct VideoInput {
    log_time_ns: u64,
    data: MessageBytes,
}

impl Weighed for VideoInput {
    fn bytes(&self) -> usize {
        self.data.len()
    }
}

/// The receiving side's handle on the video thread.
pub struct VideoFeed {
    inputs: QueueSender<VideoInput>,
    camera_index: usize,
    limit: RateLimit,
    admitted: u64,
    thread: JoinHandle<VideoReport>,
}

impl VideoFeed {
    /// Starts the video thread. The encoder is created here, so a codec that cannot start is
    /// an error of the recorder's start, not of its first frame.
    pub fn spawn(
        settings: VideoFeedSettings,
        channels: VideoChannels,
        enqueuer: Enqueuer,
        session_clock: ClockPair,
    ) -> std::io::Result<Self> {
        let encoder = H264Encoder::new(settings.video)
            .map_err(|error| std::io::Error::other(error.to_string()))?;
        let (inputs, receiver) = shared_queue::bounded(MAX_PENDING_FRAMES, MAX_PENDING_BYTES);
        let offset_ns = session_clock.realtime_offset_ns();
        let worker = Worker {
            encoder,
            enqueuer,
            channels,
            depth_every: settings.depth_every.max(1),
            wall_offset_ns: offset_ns,
            report: VideoReport::default(),
            video_sequence: 0,
            depth_sequence: 0,
        };
        let thread = std::thread::Builder::new()
            .name("recorder-video".to_owned())
            .spawn(move || worker.run(receiver))?;
        let interval = Duration::from_secs_f64(1.0 / settings.video.frame_rate_hz.max(0.001));
        Ok(Self {
            inputs,
            camera_index: channels.camera,
            limit: RateLimit::new(Some(interval)),
            admitted: 0,
            thread,
        })
    }

    /// True for the camera's catalogue index.
    pub fn is_camera(&self, index: usize) -> bool {
        index == self.camera_index
    }

    /// True when catalogue topic `index` is the camera and a frame received at `log_time_ns` is
    /// due for the video (the rate's slot is taken by this call).
    pub fn due(&mut self, index: usize, log_time_ns: u64) -> bool {
        if index != self.camera_index || !self.limit.admit(log_time_ns) {
            return false;
        }
        self.admitted += 1;
        true
    }

    /// Hands a due frame to the encoder (shared, not copied); dropped and counted when the
    /// encoder is behind.
    pub fn offer(&mut self, log_time_ns: u64, data: &MessageBytes) {
        self.inputs.offer(VideoInput {
            log_time_ns,
            data: Arc::clone(data),
        });
    }

    /// Encodes what is still queued and stops the thread.
    pub fn finish(self) -> VideoReport {
        let dropped_behind = self.inputs.dropped();
        drop(self.inputs);
        let mut report = self.thread.join().unwrap_or_else(|_| {
            tracing::error!("the recorder's video thread panicked; the camera video is incomplete");
            VideoReport::default()
        });
        report.admitted = self.admitted;
        report.dropped_behind = dropped_behind;
        report
    }
}

struct Worker {
    encoder: H264Encoder,
    enqueuer: Enqueuer,
    channels: VideoChannels,
    depth_every: u32,
    /// Realtime minus monotonic of the session: the video's timestamps are wall-clock time,
    /// like the file's log times and the mapped channels' stamps.
    wall_offset_ns: i128,
    report: VideoReport,
    video_sequence: u32,
    depth_sequence: u32,
}

impl Worker {
    fn run(mut self, inputs: QueueReceiver<VideoInput>) -> VideoReport {
        let mut access_unit = Vec::new();
        let mut warned = false;
        while let Some(input) = inputs.recv() {
            if let Err(error) = self.frame(&input, &mut access_unit) {
                self.report.failed += 1;
                if !std::mem::replace(&mut warned, true) {
                    tracing::warn!(%error, "cannot record a camera frame as video");
                }
            }
            self.enqueuer.release(input.data);
        }
        self.report
    }

    fn frame(&mut self, input: &VideoInput, access_unit: &mut Vec<u8>) -> Result<(), String> {
        let parts = split_encoded_frame(&input.data).map_err(|error| error.to_string())?;
        let width = parts.meta.rgb_intrinsics.width_px as usize;
        let height = parts.meta.rgb_intrinsics.height_px as usize;
        let (width, height) = if width * height * 3 == parts.rgb.len() {
            (width, height)
        } else {
            (
                harvest_ipc::payloads::rgbd_frame::RGB_WIDTH_PX,
                harvest_ipc::payloads::rgbd_frame::RGB_HEIGHT_PX,
            )
        };
        let publish_ns = parts.header.publish_ns;
        if self
            .report
            .encoded
            .is_multiple_of(u64::from(self.depth_every))
        {
            let mut depth = Vec::new();
            encode_depth_message(&parts, &mut depth).map_err(|error| error.to_string())?;
            self.depth_sequence = self.depth_sequence.wrapping_add(1);
            let bytes = depth.len() as u64;
            if self.queue(
                self.channels.depth,
                self.depth_sequence,
                input,
                publish_ns,
                depth,
            ) {
                self.report.depth_encoded += 1;
                self.report.depth_bytes += bytes;
            }
        }
        let started = Instant::now();
        let encoded = self
            .encoder
            .encode_rgb8(parts.rgb, width, height, access_unit)
            .map_err(|error| error.to_string())?;
        let encode_ms = started.elapsed().as_secs_f64() * 1e3;
        self.report.encoded += 1;
        self.report.keyframes += u64::from(encoded.keyframe);
        self.report.encode_ms_total += encode_ms;
        self.report.encode_ms_max = self.report.encode_ms_max.max(encode_ms);
        tracing::trace!(
            bytes = encoded.size_bytes,
            keyframe = encoded.keyframe,
            encode_ms,
            "video frame"
        );
        let capture_wall_ns = (i128::from(parts.header.capture_ns) + self.wall_offset_ns)
            .clamp(0, i128::from(u64::MAX)) as u64;
        let mut message = Vec::with_capacity(access_unit.len() + 64);
        encode_video_message(capture_wall_ns, access_unit, &mut message);
        self.video_sequence = self.video_sequence.wrapping_add(1);
        let bytes = message.len() as u64;
        if self.queue(
            self.channels.video,
            self.video_sequence,
            input,
            publish_ns,
            message,
        ) {
            self.report.video_bytes += bytes;
        }
        Ok(())
    }

    fn queue(
        &mut self,
        topic: usize,
        sequence: u32,
        input: &VideoInput,
        publish_ns: u64,
        data: Vec<u8>,
    ) -> bool {
        let queued = self.enqueuer.try_enqueue(QueuedMessage {
            topic,
            sequence,
            log_time_ns: input.log_time_ns,
            publish_time_ns: publish_ns,
            data: Arc::new(data),
        });
        if !queued {
            self.report.dropped_by_queue += 1;
        }
        queued
    }
}
