//! Helpers of the recorder tests: unique domains and scratch directories, a recorder running on
//! its own thread (its own node), publishers of test messages, and the independent Python
//! `mcap` reader.

#![allow(dead_code)]

use harvest_ipc::catalogue::{ARM_STATE, CAMERA_RGBD, EMERGENCY_STOP, VACUUM_STATE};
use harvest_ipc::payloads::rgbd_frame::{DEPTH_PIXELS, RGB_BYTES};
use harvest_ipc::payloads::{ArmPhase, ArmState, EmergencyStop, RgbdFrame, VacuumState};
use harvest_ipc::{Context, Domain, FixedString, Header, Payload, Publisher, WireEnum};
use harvest_recorder::recorder::CameraRecord;
use harvest_recorder::{RecorderArgs, RecorderControl, RecorderError, RecordingReport};
use harvest_recording::segment_writer::ChunkCompression;
#[allow(unused_imports)]
pub use harvest_test_support::python::{ensure_python, ensure_python_mcap, python_json};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A domain no other test (or concurrent run) uses; what it leaves in /dev/shm is removed when
/// it is dropped.
pub fn unique_domain(tag: &str) -> harvest_ipc::ScratchDomain {
    harvest_ipc::ScratchDomain::new(tag)
}

/// A scratch directory removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> Self {
        let path = std::env::temp_dir().join(format!("harvest-rec-{tag}-{}", Domain::unique("d")));
        std::fs::create_dir_all(&path).expect("create temp dir");
        Self(path)
    }

    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Recorder options for tests: output in `dir`, short timers.
pub fn test_args(dir: &Path) -> RecorderArgs {
    RecorderArgs {
        output_dir: dir.to_path_buf(),
        chunk_interval: Duration::from_millis(20),
        retry_interval: Duration::from_millis(50),
        max_total_size: 0,
        // These tests check the raw channels, the camera's frames included, as they were
        // recorded (tests/video.rs covers the camera as video).
        camera: CameraRecord::Raw,
        compression: ChunkCompression::Lz4,
        ..RecorderArgs::default()
    }
}

/// A recorder on its own thread with its own node; stop it with [`RunningRecorder::stop`].
pub struct RunningRecorder {
    pub control: Arc<RecorderControl>,
    thread: JoinHandle<Result<RecordingReport, RecorderError>>,
}

impl RunningRecorder {
    pub fn start(domain: &Domain, args: RecorderArgs) -> Self {
        let control = Arc::new(RecorderControl::new(Duration::from_millis(20)));
        let thread_control = control.clone();
        let domain = domain.clone();
        let thread = std::thread::spawn(move || {
            harvest_recorder::run_recorder_until(&args, &domain, "recorder", &thread_control)
        });
        Self { control, thread }
    }

    /// Waits until every channel is tapped (fails the test after 20 s).
    pub fn wait_ready(&self) {
        wait_until("recorder ready", || {
            self.control.ready.load(Ordering::SeqCst)
        });
    }

    pub fn stop(self) -> Result<RecordingReport, RecorderError> {
        self.control.stop.store(true, Ordering::SeqCst);
        self.thread.join().expect("recorder thread panicked")
    }
}

/// Polls `condition` every 5 ms; fails the test if it is not true within 20 s (a watchdog
/// against hangs, not a timing assertion).
pub fn wait_until(what: &str, mut condition: impl FnMut() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while !condition() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// The arm state a test sends as message `index`.
pub fn arm_state(index: u32) -> ArmState {
    ArmState {
        header: Header {
            capture_ns: 1_000_000 + u64::from(index),
            ..Header::default()
        },
        arm_id: 1,
        phase: ArmPhase::ALL[index as usize % ArmPhase::ALL.len()].into(),
        apple_id: 1000 + index,
        harvested_count: index,
        joint_position: [0.1 * index as f64, -0.2, 0.3, f64::from(index).sin()],
        control_period_ns: 5_000_000,
        ..ArmState::default()
    }
}

pub fn vacuum_state(index: u32) -> VacuumState {
    VacuumState {
        header: Header {
            capture_ns: 2_000_000 + u64::from(index),
            ..Header::default()
        },
        ..VacuumState::default()
    }
}

pub fn emergency_stop() -> EmergencyStop {
    EmergencyStop {
        header: Header {
            capture_ns: 77,
            ..Header::default()
        },
        engaged: 1,
        reason: FixedString::new("test stop"),
        ..EmergencyStop::default()
    }
}

/// Fills a frame with a deterministic pattern of `seed` (random-looking bytes, so the
/// compressor cannot shrink it to nothing).
pub fn fill_frame(frame: &mut RgbdFrame, seed: u32) {
    frame.meta = Default::default();
    frame.meta.exposure_us = 1000 + seed;
    let mut state = 0x9e37_79b9u32 ^ seed.wrapping_mul(0x85eb_ca6b);
    for byte in frame.rgb.iter_mut() {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        *byte = (state >> 24) as u8;
    }
    for (index, depth) in frame.depth_mm.iter_mut().enumerate() {
        *depth = ((index as u32 + seed * 7) % 4000) as u16;
    }
    debug_assert_eq!(frame.rgb.len(), RGB_BYTES);
    debug_assert_eq!(frame.depth_mm.len(), DEPTH_PIXELS);
}

/// Publishers of the channels most tests use.
pub struct TestPublishers {
    pub arm: Publisher<ArmState>,
    pub vacuum: Publisher<VacuumState>,
    pub stop: Publisher<EmergencyStop>,
    pub frames: Publisher<RgbdFrame>,
}

impl TestPublishers {
    pub fn open(context: &Context) -> Self {
        Self {
            arm: context.publisher(ARM_STATE[0]).expect("arm publisher"),
            vacuum: context.publisher(VACUUM_STATE).expect("vacuum publisher"),
            stop: context.publisher(EMERGENCY_STOP).expect("stop publisher"),
            frames: context.publisher(CAMERA_RGBD).expect("frame publisher"),
        }
    }

    /// Sends `arms` arm states, `vacuums` vacuum states, one emergency stop and `frames` frames.
    pub fn send(&mut self, arms: u32, vacuums: u32, frames: u32) {
        for index in 0..arms {
            self.arm.publish(&arm_state(index)).expect("publish arm");
        }
        for index in 0..vacuums {
            self.vacuum
                .publish(&vacuum_state(index))
                .expect("publish vacuum");
        }
        self.stop.publish(&emergency_stop()).expect("publish stop");
        for index in 0..frames {
            self.frames
                .publish_with(5_000 + u64::from(index), |frame| fill_frame(frame, index))
                .expect("publish frame");
        }
    }
}

/// Encoded bytes of a payload (what the recorder writes), for comparisons.
pub fn encoded<T: Payload>(value: &T) -> Vec<u8> {
    let mut bytes = Vec::new();
    value.encode(&mut bytes).expect("encode");
    bytes
}

/// Reads `path` with the Python `mcap` reader and returns its JSON description: schemas,
/// channels, metadata and every message (`data_hex` for messages under 4 KiB, else the first
/// 24 bytes as `head_hex` plus `crc32` of the rest).
pub fn python_read(path: &Path) -> serde_json::Value {
    ensure_python_mcap();
    const SCRIPT: &str = r#"
import json, sys, zlib
from mcap.reader import make_reader
out = {"messages": [], "channels": {}, "schemas": {}, "metadata": [], "has_summary": False}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    summary = reader.get_summary()
    out["has_summary"] = summary is not None
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        out["channels"][channel.topic] = {"message_encoding": channel.message_encoding, "metadata": dict(channel.metadata)}
        if schema is not None:
            out["schemas"][schema.name] = {"encoding": schema.encoding, "data": schema.data.decode("utf-8", "replace")}
        entry = {"topic": channel.topic, "schema": schema.name if schema else "", "sequence": message.sequence,
                 "log_time": message.log_time, "publish_time": message.publish_time, "size": len(message.data)}
        if len(message.data) < 4096:
            entry["data_hex"] = message.data.hex()
        else:
            entry["head_hex"] = message.data[:24].hex()
            entry["crc32"] = zlib.crc32(message.data[24:])
        out["messages"].append(entry)
    for record in reader.iter_metadata():
        out["metadata"].append({"name": record.name, "metadata": dict(record.metadata)})
print(json.dumps(out))
"#;
    python_json(SCRIPT, path)
}

/// Parses hex text into bytes.
pub fn from_hex(text: &str) -> Vec<u8> {
    (0..text.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&text[i..i + 2], 16).expect("hex"))
        .collect()
}

/// The recording files written into `dir`, sorted.
pub fn mcap_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("read dir")
        .filter_map(|entry| entry.ok().map(|entry| entry.path()))
        .filter(|path| path.extension().is_some_and(|ext| ext == "mcap"))
        .collect();
    files.sort();
    files
}
