//! Measurements (not assertions): recording throughput of 30 Hz RGB-D frames against the raw
//! disk bandwidth measured in the same run, and replay speed in `--fast` mode.
//!
//! `cargo test -p harvest-recorder --release --test measure -- --ignored --nocapture`

mod common;

use common::*;
use harvest_ipc::Context;
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::RgbdFrame;
use harvest_rec::replay::{ReplayArgs, run_replay_with};
use harvest_recording::payload_codec::zeroed_box;
use harvest_recording::segment_writer::ChunkCompression;
use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

const FRAMES: u32 = 150;
const RATE_HZ: f64 = 30.0;

/// A frame that compresses like a camera image: smooth shading plus a few levels of noise.
fn realistic_frame(seed: u32) -> Box<RgbdFrame> {
    let mut frame = zeroed_box::<RgbdFrame>();
    let mut state = 0x1234_5678u32 ^ seed;
    for (pixel, rgb) in frame.rgb.chunks_exact_mut(3).enumerate() {
        let (u, v) = ((pixel % 1920) as u32, (pixel / 1920) as u32);
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let noise = (state >> 29) as u8;
        rgb[0] = ((u / 8 + seed) % 200) as u8 + noise;
        rgb[1] = ((v / 5 + u / 13) % 180) as u8 + noise;
        rgb[2] = (((u + v) / 11) % 90) as u8 + noise;
    }
    for (index, depth) in frame.depth_mm.iter_mut().enumerate() {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        *depth = 800 + ((index % 640) as u16 / 2) + (state >> 28) as u16;
    }
    frame
}

fn raw_disk_bandwidth(dir: &Path, bytes: &[u8], count: u32) -> (f64, f64) {
    let path = dir.join("raw.bin");
    let started = Instant::now();
    let mut file =
        std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(&path).expect("create"));
    for _ in 0..count {
        file.write_all(bytes).expect("write");
    }
    let file = file.into_inner().expect("flush");
    let buffered_s = started.elapsed().as_secs_f64();
    file.sync_all().expect("sync");
    let synced_s = started.elapsed().as_secs_f64();
    let _ = std::fs::remove_file(&path);
    let total_mb = bytes.len() as f64 * f64::from(count) / 1e6;
    (total_mb / buffered_s, total_mb / synced_s)
}

#[test]
#[ignore = "measurement; run with --release --ignored --nocapture"]
fn measure_recording_and_replay_of_rgbd_frames() {
    let dir = TempDir::new("measure");
    let frames: Vec<Box<RgbdFrame>> = (0..4).map(realistic_frame).collect();
    let frame_bytes = encoded(&*frames[0]);
    let (buffered, synced) = raw_disk_bandwidth(dir.path(), &frame_bytes, FRAMES);
    println!(
        "raw disk write of {FRAMES} x {:.1} MB: {buffered:.0} MB/s to page cache, {synced:.0} MB/s including fsync",
        frame_bytes.len() as f64 / 1e6
    );
    println!(
        "input at {RATE_HZ} Hz: {:.0} MB/s",
        frame_bytes.len() as f64 * RATE_HZ / 1e6
    );
    let mut replayed_file = None;
    for (compression, level, threads, paced) in [
        (ChunkCompression::Lz4, 0, 0, true),
        (ChunkCompression::Zstd, 1, 0, true),
        (ChunkCompression::Zstd, 1, 1, true),
        (ChunkCompression::None, 0, 0, true),
        (ChunkCompression::Lz4, 0, 0, false),
    ] {
        let out = dir.path().join(format!("{}-{threads}", compression.name()));
        let domain = unique_domain("meas");
        let args = harvest_recorder::RecorderArgs {
            include: vec![CAMERA_RGBD.spec.topic.into()],
            compression,
            compression_level: Some(level),
            compression_threads: threads,
            chunk_interval: Duration::from_secs(1),
            ..test_args(&out)
        };
        let recorder = RunningRecorder::start(&domain, args);
        recorder.wait_ready();
        let context = Context::new(&domain, "camera").expect("node");
        let mut publisher = context.publisher(CAMERA_RGBD).expect("publisher");
        let started = Instant::now();
        let period = Duration::from_secs_f64(1.0 / RATE_HZ);
        for index in 0..FRAMES {
            let due = started + period * index;
            if let Some(wait) = due.checked_duration_since(Instant::now()).filter(|_| paced) {
                std::thread::sleep(wait);
            }
            let source = &frames[index as usize % frames.len()];
            publisher
                .publish_with(index.into(), |frame| {
                    frame.meta = source.meta;
                    frame.rgb.copy_from_slice(&source.rgb);
                    frame.depth_mm.copy_from_slice(&source.depth_mm);
                })
                .expect("publish");
        }
        let publish_s = started.elapsed().as_secs_f64();
        let report = recorder.stop().expect("recording");
        let stop_s = started.elapsed().as_secs_f64();
        let line = report
            .topics
            .iter()
            .find(|t| t.topic == "camera/rgbd")
            .expect("camera line");
        let input_mb = f64::from(FRAMES) * frame_bytes.len() as f64 / 1e6;
        let pacing = if paced { "30 Hz" } else { "unpaced" };
        println!(
            "{pacing:>7} {:>4} level {level} threads {threads}: {} of {FRAMES} frames written, dropped {} (buffer) + {} (queue); \
input {:.0} MB/s over {publish_s:.2} s; file {:.0} MB ({:.0}% of input), all written {stop_s:.2} s after the first frame",
            compression.name(),
            line.written,
            line.counts.dropped_by_transport,
            line.counts.dropped_by_queue,
            input_mb / publish_s,
            report.bytes_written as f64 / 1e6,
            report.bytes_written as f64 / 1e6 / input_mb * 100.0,
        );
        if replayed_file.is_none() {
            replayed_file = report.files.first().cloned();
        }
    }
    // Replay speed: the first (30 Hz, lz4) recording, as fast as possible, into a domain nobody
    // listens to.
    let file = replayed_file.expect("a recording");
    let args = ReplayArgs {
        fast: true,
        ..ReplayArgs::for_files(vec![file])
    };
    let report = run_replay_with(&args, &unique_domain("measrep"), |_| {}).expect("replay");
    println!(
        "replay --fast: {} frames, {:.2} s recorded in {:.2} s wall = {:.1}x real time",
        report.messages(),
        report.recorded_span_ns as f64 * 1e-9,
        report.wall_time.as_secs_f64(),
        report.speed_factor()
    );
}
