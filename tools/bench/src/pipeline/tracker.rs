//! Follows messages down the pipeline by their header stamps and collects per-hop latencies.
//!
//! Every stamp is `CLOCK_MONOTONIC` on this host (`harvest_ipc::MonotonicClock`), so stamps of
//! different processes subtract directly. The links between messages:
//!
//! - the device's frame (`hw/camera/rgbd`, the simulator standing in for the ToF camera) and
//!   the driver's frame (`camera/rgbd`) share `capture_ns` (the driver copies it);
//! - a camera frame (`camera/rgbd`) is `msg_seq` / `capture_ns` / `publish_ns`;
//! - `AppleDetections` names its frame by `source_frame_seq` (the frame's `msg_seq`) and
//!   `source_capture_ns`, and carries `processing_ns`;
//! - `ArmTarget` names the detection set it came from by `source_capture_ns`;
//! - `ArmCommand` names the target it follows by `apple_id` and `source_capture_ns`; the
//!   *first* command of an arm carrying a target's pair is the arm's reaction to that target.
//!
//! Messages are fed in pipeline order within one wake-up (frames, detections, targets,
//! commands), so a message's source has always been seen before it if the bench saw it at all.
//! Messages whose source was not seen (published before the bench subscribed, or overwritten in
//! a full buffer) give no sample for that hop.

use crate::pipeline::summary::{Samples, Summary};
use harvest_ipc::Header;
use serde::Serialize;
use std::collections::{HashMap, VecDeque};

/// Frames, detection sets and targets remembered for matching (about 2 s of frames at 30 Hz;
/// a source older than this is not matched).
pub const REMEMBERED: usize = 64;

/// The measured hops and end-to-end spans, in pipeline order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Frame `capture_ns` -> its `camera/rgbd` `publish_ns` (device capture, transfer from the
    /// device, the driver's copy into the loan).
    CameraPublish,
    /// Frame `capture_ns` -> its `hw/camera/rgbd` `publish_ns`: the device's part of
    /// [`Stage::CameraPublish`] (in simulation: rendering the frame).
    DeviceFrame,
    /// `hw/camera/rgbd` `publish_ns` -> `camera/rgbd` `publish_ns` of the same capture: the
    /// driver's part of [`Stage::CameraPublish`] (receive, copy into its loan, publish).
    DriverFrame,
    /// `camera/rgbd` `publish_ns` -> the `perception/apples` `publish_ns` of that frame.
    PerceptionResult,
    /// `processing_ns` of each detection set: the compute part of [`Stage::PerceptionResult`].
    PerceptionProcessing,
    /// `perception/apples` `publish_ns` -> `armN/target` `publish_ns` of a target from it.
    ArmTarget,
    /// `armN/target` `publish_ns` -> `publish_ns` of the arm's first `armN/command` for it.
    ArmCommand,
    /// End to end: frame `capture_ns` -> `perception/apples` `publish_ns`.
    CaptureToDetections,
    /// End to end: frame `capture_ns` -> the first `armN/command` following a target from it.
    CaptureToCommand,
}

impl Stage {
    /// The per-hop breakdown, in pipeline order.
    pub const HOPS: [Stage; 7] = [
        Self::CameraPublish,
        Self::DeviceFrame,
        Self::DriverFrame,
        Self::PerceptionResult,
        Self::PerceptionProcessing,
        Self::ArmTarget,
        Self::ArmCommand,
    ];
    /// The end-to-end spans.
    pub const END_TO_END: [Stage; 2] = [Self::CaptureToDetections, Self::CaptureToCommand];

    pub fn name(self) -> &'static str {
        match self {
            Self::CameraPublish => "capture -> camera/rgbd",
            Self::DeviceFrame => "  of which device (hw/camera/rgbd)",
            Self::DriverFrame => "  of which camera driver",
            Self::PerceptionResult => "camera/rgbd -> perception/apples",
            Self::PerceptionProcessing => "  of which perception processing",
            Self::ArmTarget => "perception/apples -> armN/target",
            Self::ArmCommand => "armN/target -> armN/command",
            Self::CaptureToDetections => "capture -> perception/apples",
            Self::CaptureToCommand => "capture -> armN/command",
        }
    }

    /// The channels whose messages this stage needs (for the "no data" note).
    pub fn channels(self) -> &'static str {
        match self {
            Self::CameraPublish => "camera/rgbd",
            Self::DeviceFrame => "hw/camera/rgbd",
            Self::DriverFrame => "hw/camera/rgbd and camera/rgbd",
            Self::PerceptionResult => "camera/rgbd and perception/apples",
            Self::PerceptionProcessing | Self::CaptureToDetections => "perception/apples",
            Self::ArmTarget => "perception/apples and armN/target",
            Self::ArmCommand | Self::CaptureToCommand => {
                "armN/target and armN/command (with apple_id and source_capture_ns)"
            }
        }
    }
}

/// The stamps of one frame.
#[derive(Debug, Clone, Copy)]
struct FrameStamps {
    msg_seq: u64,
    capture_ns: u64,
    publish_ns: u64,
}

/// A bounded memory of recent items, oldest dropped first.
#[derive(Debug)]
struct Recent<K, V> {
    order: VecDeque<K>,
    items: HashMap<K, V>,
}

impl<K: Copy + Eq + std::hash::Hash, V> Recent<K, V> {
    fn new() -> Self {
        Self {
            order: VecDeque::with_capacity(REMEMBERED + 1),
            items: HashMap::with_capacity(REMEMBERED + 1),
        }
    }

    /// Inserts unless `key` is already known (the first sighting wins).
    fn insert_first(&mut self, key: K, value: V) {
        if self.items.contains_key(&key) {
            return;
        }
        self.order.push_back(key);
        self.items.insert(key, value);
        while self.order.len() > REMEMBERED {
            if let Some(old) = self.order.pop_front() {
                self.items.remove(&old);
            }
        }
    }

    fn get(&self, key: &K) -> Option<&V> {
        self.items.get(key)
    }

    fn get_mut(&mut self, key: &K) -> Option<&mut V> {
        self.items.get_mut(key)
    }
}

/// A target waiting for the arm's first command that follows it.
#[derive(Debug, Clone, Copy)]
struct PendingTarget {
    publish_ns: u64,
    answered: bool,
}

/// Collects the stage latencies of one run.
#[derive(Debug)]
pub struct PipelineTracker {
    recording: bool,
    /// `hw/camera/rgbd` `publish_ns` by `capture_ns`.
    device_frames: Recent<u64, u64>,
    frames_by_seq: Recent<u64, FrameStamps>,
    /// `perception/apples` `publish_ns` by `source_capture_ns`.
    detections: Recent<u64, u64>,
    /// Per arm: targets by (`apple_id`, `source_capture_ns`).
    targets: [Recent<(u32, u64), PendingTarget>; 2],
    samples: HashMap<Stage, Samples>,
}

impl Default for PipelineTracker {
    fn default() -> Self {
        Self::new()
    }
}

impl PipelineTracker {
    pub fn new() -> Self {
        Self {
            recording: false,
            device_frames: Recent::new(),
            frames_by_seq: Recent::new(),
            detections: Recent::new(),
            targets: [Recent::new(), Recent::new()],
            samples: HashMap::new(),
        }
    }

    /// Starts recording samples (after the warm-up). Before, messages are only remembered so
    /// the first recorded hops find their sources.
    pub fn start_recording(&mut self) {
        self.recording = true;
    }

    fn record(&mut self, stage: Stage, from_ns: u64, to_ns: u64) {
        if self.recording && from_ns > 0 && to_ns >= from_ns {
            self.samples.entry(stage).or_default().push(to_ns - from_ns);
        }
    }

    /// A device frame on `hw/camera/rgbd`.
    pub fn on_device_frame(&mut self, header: &Header) {
        self.device_frames
            .insert_first(header.capture_ns, header.publish_ns);
        self.record(Stage::DeviceFrame, header.capture_ns, header.publish_ns);
    }

    /// A `camera/rgbd` frame.
    pub fn on_frame(&mut self, header: &Header) {
        if let Some(&device_publish_ns) = self.device_frames.get(&header.capture_ns) {
            self.record(Stage::DriverFrame, device_publish_ns, header.publish_ns);
        }
        self.frames_by_seq.insert_first(
            header.msg_seq,
            FrameStamps {
                msg_seq: header.msg_seq,
                capture_ns: header.capture_ns,
                publish_ns: header.publish_ns,
            },
        );
        self.record(Stage::CameraPublish, header.capture_ns, header.publish_ns);
    }

    /// A `perception/apples` detection set.
    pub fn on_detections(
        &mut self,
        header: &Header,
        source_frame_seq: u64,
        source_capture_ns: u64,
        processing_ns: u64,
    ) {
        if let Some(frame) = self.frames_by_seq.get(&source_frame_seq).copied()
            && frame.msg_seq == source_frame_seq
            && frame.capture_ns == source_capture_ns
        {
            self.record(Stage::PerceptionResult, frame.publish_ns, header.publish_ns);
        }
        if self.recording && processing_ns > 0 {
            self.samples
                .entry(Stage::PerceptionProcessing)
                .or_default()
                .push(processing_ns);
        }
        self.record(
            Stage::CaptureToDetections,
            source_capture_ns,
            header.publish_ns,
        );
        self.detections
            .insert_first(source_capture_ns, header.publish_ns);
    }

    /// An `armN/target` (`arm_index` 0 or 1). A target re-published with the same apple and
    /// source counts once.
    pub fn on_target(
        &mut self,
        arm_index: usize,
        header: &Header,
        apple_id: u32,
        source_capture_ns: u64,
    ) {
        let Some(targets) = self.targets.get_mut(arm_index) else {
            return;
        };
        if targets.get(&(apple_id, source_capture_ns)).is_some() {
            return;
        }
        targets.insert_first(
            (apple_id, source_capture_ns),
            PendingTarget {
                publish_ns: header.publish_ns,
                answered: false,
            },
        );
        if let Some(&detections_publish_ns) = self.detections.get(&source_capture_ns) {
            self.record(Stage::ArmTarget, detections_publish_ns, header.publish_ns);
        }
    }

    /// An `armN/command`. The first command naming a known target is the arm's reaction.
    pub fn on_command(
        &mut self,
        arm_index: usize,
        header: &Header,
        apple_id: u32,
        source_capture_ns: u64,
    ) {
        if source_capture_ns == 0 {
            return;
        }
        let Some(targets) = self.targets.get_mut(arm_index) else {
            return;
        };
        let Some(target) = targets.get_mut(&(apple_id, source_capture_ns)) else {
            return;
        };
        if target.answered {
            return;
        }
        target.answered = true;
        let target_publish_ns = target.publish_ns;
        self.record(Stage::ArmCommand, target_publish_ns, header.publish_ns);
        self.record(
            Stage::CaptureToCommand,
            source_capture_ns,
            header.publish_ns,
        );
    }

    /// The distribution of `stage` (None: no sample).
    pub fn summary(&self, stage: Stage) -> Option<Summary> {
        self.samples.get(&stage).and_then(Samples::summary)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(msg_seq: u64, capture_ns: u64, publish_ns: u64) -> Header {
        Header {
            msg_seq,
            capture_ns,
            publish_ns,
        }
    }

    const MS: u64 = 1_000_000;

    /// One frame through the whole pipeline with known stamps.
    fn feed_one(tracker: &mut PipelineTracker, seq: u64, t0: u64) {
        tracker.on_device_frame(&header(seq + 100, t0, t0 + 3 * MS));
        tracker.on_frame(&header(seq, t0, t0 + 4 * MS));
        tracker.on_detections(&header(seq, t0, t0 + 30 * MS), seq, t0, 20 * MS);
        tracker.on_target(1, &header(seq, t0 + 31 * MS, t0 + 31 * MS), 7, t0);
        // A command that names nothing, then the reaction, then a repeat of it.
        tracker.on_command(1, &header(1, 0, t0 + 32 * MS), 0, 0);
        tracker.on_command(1, &header(2, 0, t0 + 34 * MS), 7, t0);
        tracker.on_command(1, &header(3, 0, t0 + 39 * MS), 7, t0);
    }

    #[test]
    fn known_stamps_give_known_hops() {
        let mut tracker = PipelineTracker::new();
        // Before recording: remembered, not measured.
        feed_one(&mut tracker, 1, 1_000 * MS);
        assert!(tracker.summary(Stage::CameraPublish).is_none());
        tracker.start_recording();
        feed_one(&mut tracker, 2, 2_000 * MS);
        feed_one(&mut tracker, 3, 3_000 * MS);
        let p50 = |stage| tracker.summary(stage).map(|s| (s.samples, s.p50_ns));
        assert_eq!(p50(Stage::CameraPublish), Some((2, 4 * MS)));
        assert_eq!(p50(Stage::DeviceFrame), Some((2, 3 * MS)));
        assert_eq!(p50(Stage::DriverFrame), Some((2, MS)));
        assert_eq!(p50(Stage::PerceptionResult), Some((2, 26 * MS)));
        assert_eq!(p50(Stage::PerceptionProcessing), Some((2, 20 * MS)));
        assert_eq!(p50(Stage::ArmTarget), Some((2, MS)));
        // Only the first command naming the target counts.
        assert_eq!(p50(Stage::ArmCommand), Some((2, 3 * MS)));
        assert_eq!(p50(Stage::CaptureToDetections), Some((2, 30 * MS)));
        assert_eq!(p50(Stage::CaptureToCommand), Some((2, 34 * MS)));
    }

    #[test]
    fn unseen_sources_and_other_arms_give_no_sample() {
        let mut tracker = PipelineTracker::new();
        tracker.start_recording();
        // Detections of a frame the bench never saw: only the end-to-end span and processing.
        tracker.on_detections(&header(1, 5 * MS, 40 * MS), 99, 5 * MS, 10 * MS);
        assert!(tracker.summary(Stage::PerceptionResult).is_none());
        assert_eq!(
            tracker
                .summary(Stage::CaptureToDetections)
                .map(|s| s.p50_ns),
            Some(35 * MS)
        );
        // A target from a detection set never seen (e.g. latched from before the bench).
        tracker.on_target(0, &header(1, 0, 50 * MS), 3, MS);
        assert!(tracker.summary(Stage::ArmTarget).is_none());
        // A command on the other arm naming it is not a reaction.
        tracker.on_command(1, &header(1, 0, 51 * MS), 3, MS);
        assert!(tracker.summary(Stage::ArmCommand).is_none());
        // On its own arm it is; a second target message for the same apple/source is ignored.
        tracker.on_target(0, &header(2, 0, 60 * MS), 3, MS);
        tracker.on_command(0, &header(2, 0, 52 * MS), 3, MS);
        assert_eq!(
            tracker.summary(Stage::ArmCommand).map(|s| s.p50_ns),
            Some(2 * MS)
        );
    }

    #[test]
    fn memory_is_bounded() {
        let mut tracker = PipelineTracker::new();
        tracker.start_recording();
        for seq in 1..=(REMEMBERED as u64 + 10) {
            tracker.on_frame(&header(seq, seq * MS, seq * MS + 1));
        }
        assert_eq!(tracker.frames_by_seq.items.len(), REMEMBERED);
        // The oldest frame is forgotten: its detections give no per-hop sample.
        tracker.on_detections(&header(1, MS, 100 * MS), 1, MS, 1);
        assert!(tracker.summary(Stage::PerceptionResult).is_none());
        let newest = REMEMBERED as u64 + 10;
        tracker.on_detections(
            &header(2, newest * MS, newest * MS + 7),
            newest,
            newest * MS,
            1,
        );
        assert_eq!(
            tracker.summary(Stage::PerceptionResult).map(|s| s.p50_ns),
            Some(6)
        );
    }
}
