//! `harvest bench video`: what the recorder's camera video costs per 1920x1080 frame on one
//! core (the RGB-to-YUV conversion and OpenH264's encoding, as the recorder's video thread does
//! them), what it takes to decode (replay), the bytes per frame at the configured bit rate, and
//! the depth image's lossless PNG: time and bytes.
//!
//! The frames: the simulator's colour and depth frame of a scenario, shifted sideways by a few
//! pixels per frame (the platform moving along the row) with deterministic per-pixel noise (a
//! real sensor's; the renderer's images are noise-free, which would flatter the encoder).

use crate::affinity::AffinityRestore;
use crate::scene_frame::{SceneFrame, SceneFrameError};
use crate::stats::percentile;
use harvest_ipc::codec;
use harvest_ipc::header::Header;
use harvest_ipc::payloads::rgbd_frame::{DEPTH_PIXELS, RgbdFrameMeta};
use harvest_recording::camera_record::{EncodedFrameParts, encode_depth_message};
use harvest_recording::video_codec::{H264Decoder, H264Encoder, VideoSettings};
use std::time::Instant;

/// Arguments of `harvest bench video`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchVideoArgs {
    /// Timed frames (after 5 untimed warm-up frames).
    #[arg(long, default_value_t = 100)]
    pub frames: u32,
    /// Video rate the encoder is set up for (frames per second; an IDR every second).
    #[arg(long, default_value_t = 10.0)]
    pub rate: f64,
    /// Target bit rate, bits per second (the recorder's `--video-bitrate`).
    #[arg(long, default_value_t = 2_000_000)]
    pub bitrate: u32,
    /// Sideways shift per frame, pixels.
    #[arg(long, default_value_t = 4)]
    pub shift_px: usize,
    /// Per-pixel noise amplitude (+-), grey levels.
    #[arg(long, default_value_t = 3)]
    pub noise: u8,
    /// Depth images per second kept (the recorder's `--depth-rate`), for the MB/s figure.
    #[arg(long, default_value_t = 2.0)]
    pub depth_rate: f64,
    /// CPU the benchmark is pinned to (one core).
    #[arg(long, default_value_t = 0)]
    pub cpu: usize,
    /// Scenario of the frame (preset or file).
    #[arg(long, default_value = "default")]
    pub scenario: String,
}

/// What `harvest bench video` measured.
#[derive(Debug, Clone, PartialEq)]
pub struct VideoBenchReport {
    pub frames: u32,
    pub encode_median_ms: f64,
    pub encode_p95_ms: f64,
    pub encode_max_ms: f64,
    pub decode_median_ms: f64,
    pub bytes_per_frame: f64,
    pub keyframe_bytes: f64,
    pub video_mb_per_s: f64,
    pub depth_png_median_ms: f64,
    pub depth_bytes: f64,
    pub depth_mb_per_s: f64,
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchVideoError {
    #[error(transparent)]
    Scene(#[from] SceneFrameError),
    #[error("video: {0}")]
    Video(String),
    #[error(transparent)]
    Affinity(#[from] crate::error::BenchError),
}

/// A deterministic noise byte for pixel `index` of frame `frame`.
fn noise(index: usize, frame: u32, amplitude: u8) -> i16 {
    if amplitude == 0 {
        return 0;
    }
    let mut state = (index as u32).wrapping_mul(0x9e37_79b9) ^ frame.wrapping_mul(0x85eb_ca6b);
    state ^= state >> 15;
    state = state.wrapping_mul(0x2c1b_3c6d);
    state ^= state >> 12;
    let span = 2 * i16::from(amplitude) + 1;
    (state % span as u32) as i16 - i16::from(amplitude)
}

/// Runs the benchmark and prints its table.
pub fn run_bench_video(args: &BenchVideoArgs) -> Result<VideoBenchReport, BenchVideoError> {
    let (
        SceneFrame {
            width_px: width,
            height_px: height,
            rgb: scene,
        },
        depth_mm,
    ) = SceneFrame::render_with_depth(&args.scenario)?;
    let _pinned = AffinityRestore::pin(args.cpu)?;

    let settings = VideoSettings::at_rate(args.rate, args.bitrate);
    let mut encoder =
        H264Encoder::new(settings).map_err(|e| BenchVideoError::Video(e.to_string()))?;
    let mut decoder = H264Decoder::new().map_err(|e| BenchVideoError::Video(e.to_string()))?;
    let mut frame = vec![0u8; scene.len()];
    let mut decoded = vec![0u8; scene.len()];
    let mut unit = Vec::new();
    let (mut encode_ms, mut decode_ms) = (Vec::new(), Vec::new());
    let (mut bytes, mut keyframe_bytes, mut keyframes) = (0usize, 0usize, 0usize);
    const WARM_UP: u32 = 5;
    for index in 0..WARM_UP + args.frames {
        // The scene shifted sideways (wrapping), plus sensor noise.
        let shift = (index as usize * args.shift_px) % width;
        for y in 0..height {
            let row = y * width * 3;
            for x in 0..width {
                let source = row + ((x + shift) % width) * 3;
                let target = row + x * 3;
                for channel in 0..3 {
                    let value = i16::from(scene[source + channel])
                        + noise(target + channel, index, args.noise);
                    frame[target + channel] = value.clamp(0, 255) as u8;
                }
            }
        }
        let started = Instant::now();
        let encoded = encoder
            .encode_rgb8(&frame, width, height, &mut unit)
            .map_err(|e| BenchVideoError::Video(e.to_string()))?;
        let encoded_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        decoder
            .decode_rgb8(&unit, &mut decoded, width, height)
            .map_err(|e| BenchVideoError::Video(e.to_string()))?;
        let decoded_ms = started.elapsed().as_secs_f64() * 1e3;
        if index >= WARM_UP {
            encode_ms.push(encoded_ms);
            decode_ms.push(decoded_ms);
            bytes += encoded.size_bytes;
            if encoded.keyframe {
                keyframes += 1;
                keyframe_bytes += encoded.size_bytes;
            }
        }
    }

    // The depth image as the recorder keeps it.
    let mut depth_le = Vec::with_capacity(DEPTH_PIXELS * 2);
    depth_le.extend(depth_mm.iter().flat_map(|depth| depth.to_le_bytes()));
    let parts = EncodedFrameParts {
        header: Header::default(),
        meta: RgbdFrameMeta::default(),
        rgb: &[],
        depth_le: &depth_le,
    };
    let mut depth_message = Vec::new();
    let mut depth_ms = Vec::new();
    for _ in 0..10 {
        let started = Instant::now();
        encode_depth_message(&parts, &mut depth_message)
            .map_err(|e| BenchVideoError::Video(e.to_string()))?;
        depth_ms.push(started.elapsed().as_secs_f64() * 1e3);
    }
    let mut prefix = Vec::new();
    let _ = codec::encode_into(&(parts.header, parts.meta), &mut prefix);

    for list in [&mut encode_ms, &mut decode_ms, &mut depth_ms] {
        list.sort_by(f64::total_cmp);
    }
    let frames = args.frames.max(1);
    let bytes_per_frame = bytes as f64 / f64::from(frames);
    let depth_bytes = depth_message.len() as f64;
    let report = VideoBenchReport {
        frames,
        encode_median_ms: percentile(&mut encode_ms, 0.5),
        encode_p95_ms: percentile(&mut encode_ms, 0.95),
        encode_max_ms: encode_ms.last().copied().unwrap_or(0.0),
        decode_median_ms: percentile(&mut decode_ms, 0.5),
        bytes_per_frame,
        keyframe_bytes: if keyframes > 0 {
            keyframe_bytes as f64 / keyframes as f64
        } else {
            0.0
        },
        video_mb_per_s: bytes_per_frame * args.rate / 1e6,
        depth_png_median_ms: percentile(&mut depth_ms, 0.5),
        depth_bytes,
        depth_mb_per_s: depth_bytes * args.depth_rate / 1e6,
    };
    println!(
        "harvest bench video: {width}x{height}, {} frames at {} frames/s, {} bit/s, shift {} px/frame, noise +-{}, pinned to CPU {}",
        report.frames, args.rate, args.bitrate, args.shift_px, args.noise, args.cpu
    );
    println!(
        "  encode (RGB->YUV + H.264), ms/frame: median {:.1}, p95 {:.1}, max {:.1} ({:.2} core at {} frames/s)",
        report.encode_median_ms,
        report.encode_p95_ms,
        report.encode_max_ms,
        report.encode_median_ms * args.rate / 1e3,
        args.rate
    );
    println!(
        "  decode (H.264 + YUV->RGB), ms/frame: median {:.1}",
        report.decode_median_ms
    );
    println!(
        "  bytes/frame {:.0} (IDR {:.0}): {:.3} MB/s of video",
        report.bytes_per_frame, report.keyframe_bytes, report.video_mb_per_s
    );
    println!(
        "  depth 640x480 PNG (lossless): {:.1} ms, {:.0} bytes ({} raw): {:.3} MB/s at {} images/s",
        report.depth_png_median_ms,
        report.depth_bytes,
        DEPTH_PIXELS * 2 + prefix.len(),
        report.depth_mb_per_s,
        args.depth_rate
    );
    Ok(report)
}
