//! The continuous record's camera as video, end to end with real shared memory and real files:
//! frames published on `camera/rgbd` at 30 Hz are recorded as H.264 (`camera/video`, 10
//! frames/s) and depth (`camera/depth`, lossless) in zstd chunks; the stream is checked with
//! our NAL parser (an IDR with SPS and PPS at least every second, no B slices) and decoded by
//! an independent decoder (Python `av`, i.e. FFmpeg), whose pictures match the published
//! ones; `replay` turns the video back into `camera/rgbd` frames with the recorded depth.

mod common;

use common::*;
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::RgbdFrame;
use harvest_ipc::payloads::rgbd_frame::{DEPTH_WIDTH_PX, RGB_WIDTH_PX};
use harvest_ipc::{Context, MonotonicClock};
use harvest_rec::replay::{ReplayArgs, ReplayEnd, run_replay_with};
use harvest_recorder::recorder::CameraRecord;
use harvest_recording::annexb::FrameNals;
use harvest_recording::camera_record::{
    DEPTH_TOPIC, VIDEO_TOPIC, decode_depth_message, decode_video_message,
};
use harvest_recording::scan::{ScanItem, ScanOptions, scan_file};
use harvest_recording::segment_writer::ChunkCompression;
use harvest_recording::time_base::FileTimeBase;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const FRAMES: u32 = 45;
/// Side of the top-left block whose grey level tells the frames apart.
const MARK_PX: usize = 64;

fn mark_level(index: u32) -> u8 {
    (20 + 4 * index).min(250) as u8
}

/// A frame with content that moves (a square crossing a gradient), a top-left block of a grey
/// level that names the frame, and a depth image of its own.
fn draw(frame: &mut RgbdFrame, index: u32) {
    frame.meta = Default::default();
    frame.meta.exposure_us = 500 + index;
    let square_x = 200 + 30 * index as usize;
    for (pixel, rgb) in frame.rgb.chunks_exact_mut(3).enumerate() {
        let (x, y) = (pixel % RGB_WIDTH_PX, pixel / RGB_WIDTH_PX);
        let value = if x < MARK_PX && y < MARK_PX {
            let level = mark_level(index);
            [level, level, level]
        } else if (square_x..square_x + 120).contains(&x) && (400..520).contains(&y) {
            [210, 40, 40]
        } else {
            [(x / 8) as u8, (y / 5) as u8, 90]
        };
        rgb.copy_from_slice(&value);
    }
    for (pixel, depth) in frame.depth_mm.iter_mut().enumerate() {
        let (x, y) = (pixel % DEPTH_WIDTH_PX, pixel / DEPTH_WIDTH_PX);
        *depth = if (x + y) % 53 == 0 {
            0
        } else {
            (700 + (x + y) / 3 + index as usize) as u16
        };
    }
}

struct Recorded {
    _dir: TempDir,
    file: PathBuf,
    /// capture_ns of each published frame.
    captures: Vec<u64>,
}

fn record() -> Recorded {
    let dir = TempDir::new("video");
    let domain = unique_domain("vsrc");
    let args = harvest_recorder::RecorderArgs {
        camera: CameraRecord::Video,
        compression: ChunkCompression::Zstd,
        ..test_args(dir.path())
    };
    let recorder = RunningRecorder::start(&domain, args);
    recorder.wait_ready();
    let context = Context::new(&domain, "publisher").expect("node");
    let mut frames = context.publisher(CAMERA_RGBD).expect("frame publisher");
    let mut captures = Vec::new();
    let started = Instant::now();
    for index in 0..FRAMES {
        // 30 frames a second, by the clock (the video rate keeps one in three).
        let due = started + Duration::from_secs_f64(f64::from(index) / 30.0);
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        let capture_ns = MonotonicClock::read_ns();
        frames
            .publish_with(capture_ns, |frame| draw(frame, index))
            .expect("publish frame");
        captures.push(capture_ns);
    }
    // Let the encoder take the last frame before the recorder stops.
    std::thread::sleep(Duration::from_millis(300));
    let report = recorder.stop().expect("recording");
    // Every frame is accounted for: taken, or counted as dropped when the machine is too busy
    // for the subscriber to keep up (the drop rate is `harvest bench video`'s to measure); the
    // checks below hold for the frames taken.
    let camera = report
        .topics
        .iter()
        .find(|topic| topic.topic == CAMERA_RGBD.spec.topic)
        .expect("camera/rgbd in the report");
    assert_eq!(
        camera.counts.received
            + camera.counts.dropped_by_transport
            + camera.counts.dropped_by_queue,
        u64::from(FRAMES),
        "{report}"
    );
    assert_eq!(report.files.len(), 1, "{report}");
    Recorded {
        _dir: dir,
        file: report.files[0].clone(),
        captures,
    }
}

/// What the file holds on the camera's channels, read with our reader.
struct CameraChannels {
    raw_frames: u64,
    /// (capture_ns on the stack clock, access unit) per video message.
    video: Vec<(u64, Vec<u8>)>,
    /// (capture_ns, depth) per depth message.
    depth: Vec<(u64, Vec<u16>)>,
    compressions: Vec<String>,
    drops: std::collections::BTreeMap<String, String>,
}

fn read_camera(file: &Path) -> CameraChannels {
    let mut time_base = FileTimeBase::default();
    let mut out = CameraChannels {
        raw_frames: 0,
        video: Vec::new(),
        depth: Vec::new(),
        compressions: Vec::new(),
        drops: Default::default(),
    };
    scan_file(file, ScanOptions::default(), |item| {
        match item {
            ScanItem::Metadata(record) => {
                time_base.observe(record);
                if record.name == "harvest.drops" {
                    out.drops = record.metadata.clone();
                }
            }
            ScanItem::Chunk(chunk) => out.compressions.push(chunk.compression.clone()),
            ScanItem::Message(message) => match message.channel.topic.as_str() {
                "camera/rgbd" => out.raw_frames += 1,
                VIDEO_TOPIC => {
                    assert_eq!(
                        message.channel.schema.as_ref().expect("schema").name,
                        "foxglove.CompressedVideo"
                    );
                    let video = decode_video_message(message.data).expect("video message");
                    out.video
                        .push((time_base.stack_ns(video.capture_wall_ns), video.access_unit));
                }
                DEPTH_TOPIC => {
                    let mut depth = vec![0u16; harvest_ipc::payloads::rgbd_frame::DEPTH_PIXELS];
                    let (header, _) =
                        decode_depth_message(message.data, &mut depth).expect("depth message");
                    out.depth.push((header.capture_ns, depth));
                }
                _ => {}
            },
            _ => {}
        }
        ControlFlow::Continue(())
    })
    .expect("scan");
    out
}

/// The independent decoder: Python `av` (FFmpeg) decodes the concatenated access units and
/// reports, per picture, its type, size and the mean grey of the top-left block.
fn decode_with_av(stream: &Path) -> serde_json::Value {
    ensure_python("av", &["av"]);
    const SCRIPT: &str = r#"
import av, json, sys
codec = av.CodecContext.create("h264", "r")
pictures = []
def take(frame):
    rgb = frame.to_ndarray(format="rgb24")
    # AVPictureType: 1 I, 2 P, 3 B.
    pictures.append({"type": int(frame.pict_type), "key": bool(frame.key_frame),
        "width": frame.width, "height": frame.height, "mark": float(rgb[:64, :64, :].mean())})
with open(sys.argv[1], "rb") as f:
    data = f.read()
for packet in codec.parse(data) + codec.parse(None):
    for frame in codec.decode(packet):
        take(frame)
for frame in codec.decode(None):
    take(frame)
print(json.dumps({"pictures": pictures}))
"#;
    python_json(SCRIPT, stream)
}

#[test]
fn the_camera_is_recorded_as_h264_that_ffmpeg_decodes_and_replay_turns_back_into_frames() {
    let recorded = record();
    let camera = read_camera(&recorded.file);

    // The raw frames stay out of the continuous record; its chunks are zstd.
    assert_eq!(camera.raw_frames, 0);
    assert!(!camera.compressions.is_empty());
    assert!(
        camera.compressions.iter().all(|c| c == "zstd"),
        "{:?}",
        camera.compressions
    );
    // Frames at up to 30 Hz (slower on a loaded machine): the 10 frames/s video keeps at most
    // one per 100 ms. What the encoder could not keep up with is dropped and counted, never
    // waited for: every admitted frame is encoded or counted.
    let videos = camera.video.len();
    let span_s =
        (recorded.captures[recorded.captures.len() - 1] - recorded.captures[0]) as f64 * 1e-9;
    let count = |key: &str| -> u64 {
        camera
            .drops
            .get(&format!("camera/video.{key}"))
            .unwrap_or_else(|| panic!("camera/video.{key} in harvest.drops: {:?}", camera.drops))
            .parse()
            .expect("count")
    };
    assert_eq!(count("encoded"), videos as u64);
    assert_eq!(count("failed"), 0);
    assert_eq!(
        count("admitted"),
        count("encoded") + count("dropped_behind") + count("dropped_queue"),
        "{:?}",
        camera.drops
    );
    assert!(
        videos >= 3 && videos as f64 <= span_s * 10.0 + 1.0,
        "{videos} video frames over {span_s:.2} s ({:?})",
        camera.drops
    );

    // Our NAL parser: an IDR with SPS and PPS first and at least every 10 frames (one second),
    // no B slices, one picture per message.
    let mut since_idr = None::<usize>;
    for (index, (_, unit)) in camera.video.iter().enumerate() {
        let nals = FrameNals::of(unit).expect("Annex B");
        assert!(!nals.has_b_slices(), "video frame {index} has B slices");
        assert!(
            nals.slice_count() >= 1,
            "video frame {index} has no picture"
        );
        if nals.is_idr() {
            assert!(nals.idr_has_parameter_sets(), "IDR {index} without SPS/PPS");
            since_idr = Some(0);
        } else {
            let frames = since_idr.expect("the video starts with an IDR") + 1;
            assert!(
                frames < 10,
                "video frame {index}: {frames} frames since the last IDR"
            );
            since_idr = Some(frames);
        }
    }
    // Each video frame is a published frame (its capture stamp), in order.
    let published: Vec<usize> = camera
        .video
        .iter()
        .map(|(capture_ns, _)| {
            recorded
                .captures
                .iter()
                .position(|c| c == capture_ns)
                .expect("the video's timestamp is a published frame's capture_ns")
        })
        .collect();
    assert!(published.windows(2).all(|pair| pair[0] < pair[1]));

    // Depth: every fifth video frame (2 of 10 frames/s), lossless, with that frame's capture.
    assert_eq!(camera.depth.len(), videos.div_ceil(5));
    for (capture_ns, depth) in &camera.depth {
        let index = recorded
            .captures
            .iter()
            .position(|c| c == capture_ns)
            .expect("depth of a published frame");
        assert!(camera.video.iter().any(|(video, _)| video == capture_ns));
        let mut expected: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
        draw(&mut expected, index as u32);
        assert!(depth[..] == expected.depth_mm[..], "depth of frame {index}");
    }

    // The independent decoder.
    let stream = recorded.file.with_extension("h264");
    let bytes: Vec<u8> = camera
        .video
        .iter()
        .flat_map(|(_, unit)| unit.iter().copied())
        .collect();
    std::fs::write(&stream, &bytes).expect("write stream");
    let decoded = decode_with_av(&stream);
    let pictures = decoded["pictures"].as_array().expect("pictures");
    assert_eq!(pictures.len(), videos, "FFmpeg decodes every video frame");
    for (picture, &index) in pictures.iter().zip(&published) {
        assert_eq!(picture["width"], 1920);
        assert_eq!(picture["height"], 1080);
        let kind = picture["type"].as_u64().expect("picture type");
        assert!(
            kind == 1 || kind == 2,
            "picture type {kind} (1 I, 2 P; 3 would be B)"
        );
        let mark = picture["mark"].as_f64().expect("mark");
        let expected = f64::from(mark_level(index as u32));
        assert!(
            (mark - expected).abs() < 6.0,
            "frame {index}: FFmpeg shows grey {mark:.1}, published {expected}"
        );
    }
    assert!(pictures[0]["key"].as_bool().expect("key"));

    // Replay: camera/rgbd frames again, one per video frame, with the recorded depth.
    let target = unique_domain("vdst");
    let context = Context::new(&target, "listener").expect("node");
    let frames = context
        .subscriber_with_buffer(CAMERA_RGBD, CAMERA_RGBD.spec.qos.subscriber_max_buffer_size)
        .expect("subscriber");
    let domain = harvest_ipc::Domain::clone(&target);
    let file = recorded.file.clone();
    let (release, released) = std::sync::mpsc::channel::<()>();
    let replay = std::thread::spawn(move || {
        // Selected by the topic the frames are replayed on, as a user would.
        let args = ReplayArgs {
            include: vec!["camera/rgbd".to_owned()],
            ..ReplayArgs::for_files(vec![file])
        };
        run_replay_with(&args, &domain, |_| {
            let _ = released.recv();
        })
        .expect("replay")
    });
    let mut replayed = Vec::new();
    wait_until("replayed frames", || {
        while let Some(frame) = frames.receive().expect("receive") {
            let index = recorded
                .captures
                .iter()
                .position(|c| *c == frame.header.capture_ns)
                .expect("a replayed frame has a published frame's capture_ns");
            let mut expected: Box<RgbdFrame> = harvest_ipc::payload::boxed_zeroed();
            draw(&mut expected, index as u32);
            let block = &frame.rgb[..MARK_PX * 3];
            let mean = block.iter().map(|&v| f64::from(v)).sum::<f64>() / block.len() as f64;
            assert!(
                (mean - f64::from(mark_level(index as u32))).abs() < 6.0,
                "replayed frame {index}: grey {mean:.1}"
            );
            // The depth kept for this frame, or the newest kept before it.
            let depth_from = camera
                .depth
                .iter()
                .rev()
                .find(|(capture_ns, _)| *capture_ns <= frame.header.capture_ns)
                .expect("depth before the frame");
            assert!(
                frame.depth_mm[..] == depth_from.1[..],
                "depth of replayed frame {index}"
            );
            replayed.push(index);
        }
        replayed.len() == videos
    });
    let _ = release.send(());
    let report = replay.join().expect("replay thread");
    assert_eq!(report.end, ReplayEnd::Finished);
    assert_eq!(report.frames_from_video, videos as u64, "{report}");
    assert_eq!(replayed, published);
    assert!(report.skipped.is_empty(), "{report}");
    println!(
        "{videos} video frames over {span_s:.2} s, {} bytes of video, {} depth images; {:?}; {report}",
        bytes.len(),
        camera.depth.len(),
        camera.drops
    );
}
