//! `harvest bench camera-gige`: the GigE Vision camera driver end to end on loopback.
//!
//! Aravis's fake GigE Vision camera ([`harvest_aravis::FakeCamera`], GVCP/GVSP over UDP) runs
//! in this process; `harvest camera --device gige` runs as its own process in a scratch domain
//! and opens it at 127.0.0.1; this process subscribes to `camera/rgbd` and to the health
//! channel. Each frame the fake sends carries, in a band of 8x8-pixel blocks along its top edge,
//! the 64 bits of the fake's own timestamp of that frame (the camera's timestamp; the fake stamps
//! with the host's `CLOCK_REALTIME`), written in the camera's pixel format so that they survive
//! demosaicing. Measured for `--duration`:
//!
//! - frames the fake sent and frames published on `camera/rgbd` (gaps in `msg_seq` and the
//!   driver's own lost-frame count from its heartbeat),
//! - latency from the camera's timestamp (decoded from the frame, converted to the stack clock)
//!   to the frame's publication on `camera/rgbd` (`header.publish_ns`) and to its arrival here,
//!   and from the driver's `capture_ns` (the camera's timestamp through the driver's clock
//!   mapping) to publication,
//! - the `harvest camera` process's CPU time per second.

use crate::driver_child::DriverChild;
use crate::proc_cpu::cpu_time_s;
use crate::stats::{LatencySummary, latency_histogram};
use harvest_aravis::{Aravis, FakeCamera, FakeImage, LoopbackCameraLock};
use harvest_hw::rgbd_camera::gige::PixelFormat;
use harvest_ipc::catalogue::{CAMERA_RGBD, PROCESS_HEALTH};
use harvest_ipc::duration::parse_duration;
use harvest_ipc::payloads::rgbd_frame::RGB_WIDTH_PX;
use harvest_ipc::{Context, MonotonicClock, ScratchDomain};
use serde::Serialize;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// Side of one block of the timestamp band, pixels.
const BLOCK_PX: usize = 8;
/// Bits of the timestamp band.
const BITS: usize = 64;

/// Options of `harvest bench camera-gige`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchCameraGigeArgs {
    /// How long to measure (after the stream settles).
    #[arg(long, value_parser = parse_duration, default_value = "60s")]
    pub duration: Duration,
    /// Pixel format the camera sends (Mono8, BayerRG8, BayerGR8, BayerGB8, BayerBG8, RGB8).
    #[arg(long, default_value = "BayerRG8", value_parser = parse_format)]
    pub pixel_format: PixelFormat,
    /// Frame rate asked of the camera, Hz.
    #[arg(long, default_value_t = 30.0)]
    pub frame_rate_hz: f64,
    /// Stream packet size, bytes.
    #[arg(long, default_value_t = 8000)]
    pub packet_size_bytes: u32,
    /// Write the report as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The `harvest` executable to run `harvest camera` from (default: this one).
    #[arg(long)]
    pub harvest_exe: Option<PathBuf>,
}

fn parse_format(text: &str) -> Result<PixelFormat, String> {
    PixelFormat::ALL
        .into_iter()
        .find(|format| format!("{format:?}") == text)
        .ok_or_else(|| {
            format!(
                "unknown pixel format {text:?} (one of {:?})",
                PixelFormat::ALL
            )
        })
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum CameraGigeBenchError {
    #[error("aravis: {0}")]
    Aravis(#[from] harvest_aravis::AravisError),
    #[error(transparent)]
    Ipc(#[from] harvest_ipc::error::IpcError),
    #[error("starting {exe}: {source}")]
    Spawn {
        exe: PathBuf,
        source: std::io::Error,
    },
    #[error("{0}")]
    Failed(String),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

harvest_ipc::from_ipc_errors!(CameraGigeBenchError);

/// A latency distribution with its 95th percentile.
#[derive(Debug, Clone, Serialize)]
pub struct CameraLatency {
    #[serde(flatten)]
    pub summary: LatencySummary,
    pub p95_ns: u64,
}

impl CameraLatency {
    fn from_histogram(histogram: &hdrhistogram::Histogram<u64>) -> Self {
        Self {
            summary: LatencySummary::from_histogram(histogram),
            p95_ns: histogram.value_at_quantile(0.95),
        }
    }
}

/// The figures.
#[derive(Debug, Clone, Serialize)]
pub struct CameraGigeReport {
    pub tool: &'static str,
    pub pixel_format: String,
    pub width_px: usize,
    pub height_px: usize,
    pub duration_s: f64,
    /// Frames the fake camera sent while measured.
    pub frames_sent: u64,
    /// Frames published on `camera/rgbd` and received here.
    pub frames_received: u64,
    pub frames_per_s: f64,
    /// Gaps in `camera/rgbd`'s `msg_seq` (frames published but not received here).
    pub channel_gaps: u64,
    /// The driver's lost frames (incomplete or missing from the camera's ids) while measured.
    pub lost_frames_driver: u64,
    /// Frames whose timestamp band could not be read.
    pub undecoded_frames: u64,
    /// The camera's timestamp -> publication on `camera/rgbd`.
    pub camera_to_publish: CameraLatency,
    /// The camera's timestamp -> arrival at this subscriber.
    pub camera_to_subscriber: CameraLatency,
    /// The driver's `capture_ns` -> publication.
    pub capture_to_publish: CameraLatency,
    /// CPU seconds of the `harvest camera` process per second.
    pub cpu_s_per_s: f64,
}

/// The nanoseconds `CLOCK_REALTIME` is ahead of `CLOCK_MONOTONIC`, read side by side.
fn realtime_minus_monotonic_ns() -> i128 {
    use nix::time::{ClockId, clock_gettime};
    let read = |clock| {
        clock_gettime(clock)
            .map(|t| i128::from(t.tv_sec()) * 1_000_000_000 + i128::from(t.tv_nsec()))
            .unwrap_or(0)
    };
    let realtime = read(ClockId::CLOCK_REALTIME);
    realtime - read(ClockId::CLOCK_MONOTONIC)
}

/// A test pattern (diagonal stripes) with the timestamp band written over its top rows.
fn fill(image: &mut FakeImage<'_>, sent: &AtomicU64) {
    let Some(format) = PixelFormat::from_code(image.pixel_format) else {
        return;
    };
    let bytes_per_pixel = format.bytes_per_pixel();
    let width = image.width as usize;
    if width < BITS * BLOCK_PX || image.height < BLOCK_PX as u32 {
        return;
    }
    for (index, byte) in image.data.iter_mut().enumerate() {
        let pixel = index / bytes_per_pixel;
        *byte = (((pixel % width) + pixel / width) % 200) as u8 + 20;
    }
    for bit in 0..BITS {
        let value = if (image.timestamp_ns >> bit) & 1 == 1 {
            255
        } else {
            0
        };
        for y in 0..BLOCK_PX {
            let row = y * width + bit * BLOCK_PX;
            image.data[row * bytes_per_pixel..(row + BLOCK_PX) * bytes_per_pixel].fill(value);
        }
    }
    sent.fetch_add(1, Ordering::Relaxed);
}

/// The timestamp in a frame's band (RGB8 1920 wide): each block's centre pixel, red channel.
fn decode_stamp(rgb: &[u8]) -> Option<u64> {
    let mut stamp = 0u64;
    for bit in 0..BITS {
        let (x, y) = (bit * BLOCK_PX + BLOCK_PX / 2, BLOCK_PX / 2);
        let value = *rgb.get((y * RGB_WIDTH_PX + x) * 3)?;
        match value {
            0..=20 => {}
            235..=255 => stamp |= 1 << bit,
            _ => return None,
        }
    }
    Some(stamp)
}

/// Runs the benchmark and prints its report.
pub fn run_bench_camera_gige(
    args: &BenchCameraGigeArgs,
) -> Result<CameraGigeReport, CameraGigeBenchError> {
    let aravis = Aravis::load()?;
    let _lock = LoopbackCameraLock::acquire()
        .map_err(|error| CameraGigeBenchError::Failed(format!("loopback camera lock: {error}")))?;
    let mut fake = FakeCamera::start(&aravis, "127.0.0.1", "HVBENCH")?;
    let sent = Arc::new(AtomicU64::new(0));
    {
        let sent = sent.clone();
        fake.set_fill(move |image| fill(image, &sent));
    }
    let domain = ScratchDomain::new("bgige");
    let dir = std::env::temp_dir().join(format!("harvest-bench-gige-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|source| CameraGigeBenchError::Write {
        path: dir.clone(),
        source,
    })?;
    let config_path = dir.join("gige.toml");
    let intrinsics = harvest_ipc::camera_model::CameraIntrinsics::tl460_rgb();
    let config = format!(
        "pixel_format = \"{:?}\"\nframe_rate_hz = {}\npacket_size_bytes = {}\n\n[intrinsics]\n\
         width_px = {}\nheight_px = {}\nfx_px = {:?}\nfy_px = {:?}\ncx_px = {:?}\ncy_px = {:?}\n\
         distortion = {:?}\n",
        args.pixel_format,
        args.frame_rate_hz,
        args.packet_size_bytes,
        intrinsics.width_px,
        intrinsics.height_px,
        intrinsics.fx_px,
        intrinsics.fy_px,
        intrinsics.cx_px,
        intrinsics.cy_px,
        intrinsics.distortion,
    );
    std::fs::write(&config_path, config).map_err(|source| CameraGigeBenchError::Write {
        path: config_path.clone(),
        source,
    })?;
    let exe = match &args.harvest_exe {
        Some(path) => path.clone(),
        None => std::env::current_exe().map_err(|source| CameraGigeBenchError::Spawn {
            exe: PathBuf::from("<current exe>"),
            source,
        })?,
    };
    let context = Context::new(&domain, "bench-camera-gige")?;
    let frames = context.subscriber_with_buffer(CAMERA_RGBD, 3)?;
    let health = context.subscriber(PROCESS_HEALTH)?;
    let child = Command::new(&exe)
        .arg("camera")
        .args(["--device", "gige", "--camera-id", "127.0.0.1", "--config"])
        .arg(&config_path)
        .env("HARVEST_DOMAIN", domain.name())
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .map_err(|source| CameraGigeBenchError::Spawn {
            exe: exe.clone(),
            source,
        })?;
    let child = DriverChild(child);
    let pid = child.0.id();
    let lost_frames = || -> Result<u64, CameraGigeBenchError> {
        let mut lost = None;
        while let Some(beat) = health.receive()? {
            if beat.process_name.as_str() == "camera" {
                lost = Some(if beat.detail.as_str() == "lost_frames" {
                    beat.detail_value
                } else {
                    0
                });
            }
        }
        Ok(lost.unwrap_or(0))
    };

    // Settle: the first 30 frames.
    if !crate::settle::settled(&frames, 30, Duration::from_secs(30))? {
        return Err(CameraGigeBenchError::Failed(
            "fewer than 30 frames from harvest camera within 30 s".into(),
        ));
    }
    std::thread::sleep(Duration::from_millis(600));
    let lost_before = lost_frames()?;

    let histogram =
        || latency_histogram().map_err(|error| CameraGigeBenchError::Failed(error.to_string()));
    let (mut to_publish, mut to_subscriber, mut capture_to_publish) =
        (histogram()?, histogram()?, histogram()?);
    let cpu_start = cpu_time_s(pid).map_err(CameraGigeBenchError::Failed)?;
    let sent_start = sent.load(Ordering::Relaxed);
    let start = Instant::now();
    let (mut received, mut gaps, mut undecoded) = (0u64, 0u64, 0u64);
    let mut last_seq: Option<u64> = None;
    while start.elapsed() < args.duration {
        while let Some(frame) = frames.receive()? {
            let now_ns = MonotonicClock::read_ns();
            received += 1;
            let seq = frame.header.msg_seq;
            if let Some(last) = last_seq {
                gaps += seq.saturating_sub(last + 1);
            }
            last_seq = Some(seq);
            let publish_ns = frame.header.publish_ns;
            let _ = capture_to_publish
                .record(publish_ns.saturating_sub(frame.header.capture_ns).max(1));
            match decode_stamp(&frame.rgb) {
                Some(realtime_ns) => {
                    let camera_ns = i128::from(realtime_ns) - realtime_minus_monotonic_ns();
                    let since = |later: u64| (i128::from(later) - camera_ns).max(1) as u64;
                    let _ = to_publish.record(since(publish_ns));
                    let _ = to_subscriber.record(since(now_ns));
                }
                None => undecoded += 1,
            }
        }
        let left = args.duration.saturating_sub(start.elapsed());
        let _ = frames
            .listener()
            .timed_wait(|_| {}, left.min(Duration::from_millis(200)));
    }
    let elapsed_s = start.elapsed().as_secs_f64();
    let frames_sent = sent.load(Ordering::Relaxed) - sent_start;
    let cpu_s = cpu_time_s(pid).map_err(CameraGigeBenchError::Failed)? - cpu_start;
    std::thread::sleep(Duration::from_millis(600));
    let lost_frames_driver = lost_frames()?.saturating_sub(lost_before);
    drop(child);
    drop(fake);
    let _ = std::fs::remove_dir_all(&dir);

    let report = CameraGigeReport {
        tool: "harvest bench camera-gige",
        pixel_format: format!("{:?}", args.pixel_format),
        width_px: harvest_ipc::payloads::rgbd_frame::RGB_WIDTH_PX,
        height_px: harvest_ipc::payloads::rgbd_frame::RGB_HEIGHT_PX,
        duration_s: elapsed_s,
        frames_sent,
        frames_received: received,
        frames_per_s: received as f64 / elapsed_s,
        channel_gaps: gaps,
        lost_frames_driver,
        undecoded_frames: undecoded,
        camera_to_publish: CameraLatency::from_histogram(&to_publish),
        camera_to_subscriber: CameraLatency::from_histogram(&to_subscriber),
        capture_to_publish: CameraLatency::from_histogram(&capture_to_publish),
        cpu_s_per_s: cpu_s / elapsed_s,
    };
    print_report(&report);
    if let Some(path) = &args.json {
        crate::json_report::write_json_report(path, &report).map_err(|source| {
            CameraGigeBenchError::Write {
                path: path.clone(),
                source,
            }
        })?;
    }
    Ok(report)
}

fn print_report(r: &CameraGigeReport) {
    let ms = |ns: u64| ns as f64 / 1e6;
    let line = |name: &str, l: &CameraLatency| {
        println!(
            "  {name}: p50 {:.2} ms  p95 {:.2} ms  p99 {:.2} ms  max {:.2} ms ({} frames)",
            ms(l.summary.p50_ns),
            ms(l.p95_ns),
            ms(l.summary.p99_ns),
            ms(l.summary.max_ns),
            l.summary.samples
        );
    };
    println!(
        "harvest bench camera-gige: {}x{} {} for {:.1} s",
        r.width_px, r.height_px, r.pixel_format, r.duration_s
    );
    println!(
        "  frames sent {}  received {} ({:.2}/s)  channel gaps {}  lost (driver) {}  undecoded {}",
        r.frames_sent,
        r.frames_received,
        r.frames_per_s,
        r.channel_gaps,
        r.lost_frames_driver,
        r.undecoded_frames
    );
    line(
        "camera timestamp -> camera/rgbd publish",
        &r.camera_to_publish,
    );
    line("camera timestamp -> subscriber", &r.camera_to_subscriber);
    line("driver capture_ns -> publish", &r.capture_to_publish);
    println!("  harvest camera CPU {:.3} s per s", r.cpu_s_per_s);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_timestamp_band_survives_bayer_demosaicing() {
        use harvest_hw::rgbd_camera::gige::pixels::to_rgb;
        let (width, height) = (RGB_WIDTH_PX, 16);
        let stamp = 1_764_000_000_123_456_789u64;
        for format in [PixelFormat::BayerRG8, PixelFormat::Mono8, PixelFormat::RGB8] {
            let mut data = vec![0u8; width * height * format.bytes_per_pixel()];
            let mut image = FakeImage {
                data: &mut data,
                width: width as u32,
                height: height as u32,
                pixel_format: format.code(),
                frame_id: 1,
                timestamp_ns: stamp,
                exposure_us: 1,
            };
            let sent = AtomicU64::new(0);
            fill(&mut image, &sent);
            assert_eq!(sent.load(Ordering::Relaxed), 1);
            let mut rgb = vec![0u8; width * height * 3];
            to_rgb(format, width, height, &data, &mut rgb).expect("sizes fit");
            assert_eq!(decode_stamp(&rgb), Some(stamp), "{format:?}");
        }
    }
}
