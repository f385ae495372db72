//! The camera view: on a thread of its own, at its own rate, the newest `camera/rgbd` frame is
//! read in place in shared memory, box-filtered down to the view size, released, and encoded
//! as JPEG. The thread wakes on the camera's frame event and encodes a frame when at least one
//! view period has passed since the last view (so a view waits for no timer after its frame
//! arrives); a timer at the view rate catches a frame whose event came too early. The camera never waits for it: the channel drops the oldest frame for a subscriber
//! that is behind (safe overflow), and this subscriber keeps a one-frame buffer.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};
use harvest_ipc::{Context, Domain, Flow, MonotonicClock, Waiter};
use harvest_perception::downscale::downscale_rgb;
use image::ImageEncoder;

use crate::error::ConsoleError;

/// One encoded view.
#[derive(Debug, Clone, PartialEq)]
pub struct EncodedFrame {
    pub jpeg: Arc<[u8]>,
    /// Counts views encoded by this console (1, 2, ...).
    pub view_seq: u64,
    /// The camera frame's `msg_seq` and `capture_ns`.
    pub frame_seq: u64,
    pub capture_ns: u64,
    /// When the JPEG was ready, ns (stack clock).
    pub encoded_ns: u64,
    pub width_px: u32,
    pub height_px: u32,
    /// Camera pixels per view pixel.
    pub scale: u32,
}

/// The newest view, shared with the HTTP threads.
#[derive(Debug, Default)]
pub struct CameraView {
    latest: Mutex<Option<Arc<EncodedFrame>>>,
    fresh: Condvar,
    /// Time spent downscaling and encoding, ns (for the status panel).
    pub work_ns: AtomicU64,
}

impl CameraView {
    /// The newest view.
    pub fn latest(&self) -> Option<Arc<EncodedFrame>> {
        self.latest
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .clone()
    }

    /// A view newer than `after_seq`, waiting up to `timeout`; else the newest (or none).
    pub fn wait_newer(&self, after_seq: u64, timeout: Duration) -> Option<Arc<EncodedFrame>> {
        let guard = self
            .latest
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let (guard, _) = self
            .fresh
            .wait_timeout_while(guard, timeout, |latest| {
                latest
                    .as_ref()
                    .is_none_or(|frame| frame.view_seq <= after_seq)
            })
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        guard.clone()
    }

    fn publish(&self, frame: EncodedFrame) {
        *self
            .latest
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = Some(Arc::new(frame));
        self.fresh.notify_all();
    }
}

/// JPEG of an RGB8 image.
pub fn encode_jpeg(
    rgb: &[u8],
    width: u32,
    height: u32,
    quality: u8,
    out: &mut Vec<u8>,
) -> Result<(), image::ImageError> {
    out.clear();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut *out, quality).write_image(
        rgb,
        width,
        height,
        image::ExtendedColorType::Rgb8,
    )
}

/// How the view is made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewSettings {
    /// Views per second.
    pub rate_hz: f64,
    /// Camera pixels per view pixel (3: 640x360 from 1920x1080).
    pub scale: u32,
    /// JPEG quality 1-100.
    pub jpeg_quality: u8,
}

/// Runs the camera view until SIGINT/SIGTERM.
pub fn run_camera_view(
    domain: &Domain,
    node_name: &str,
    settings: ViewSettings,
    view: &CameraView,
) -> Result<(), ConsoleError> {
    let context = Context::new(domain, node_name)?;
    let frames = context.subscriber_with_buffer(CAMERA_RGBD, 1)?;
    let waiter = Waiter::new()?;
    let period = Duration::from_secs_f64(1.0 / settings.rate_hz);
    let tick = waiter.attach_interval(period)?;
    let frame_event = waiter.attach_listener(frames.listener())?;
    let period_ns = period.as_nanos() as u64;
    let mut last_view_ns = 0u64;
    let scale = settings.scale.max(1) as usize;
    let (width, height) = (RGB_WIDTH_PX / scale, RGB_HEIGHT_PX / scale);
    let mut small = Vec::with_capacity(width * height * 3);
    let mut jpeg = Vec::with_capacity(128 * 1024);
    let mut view_seq = 0u64;
    let mut last_frame: Option<(u64, u64)> = None;
    tracing::info!(
        rate_hz = settings.rate_hz,
        width,
        height,
        "camera view running"
    );
    waiter
        .run(|attachment| -> Result<Flow, ConsoleError> {
            if !attachment.has_event_from(&tick) && !attachment.has_event_from(&frame_event) {
                return Ok(Flow::Continue);
            }
            // Slightly early is on time (a frame event a hair before the period is over).
            let now_ns = MonotonicClock::read_ns();
            if now_ns.saturating_sub(last_view_ns) < period_ns * 9 / 10 {
                // Consume the wake-up; the frame stays queued (one slot) for the next turn.
                frames.listener().try_wait(|_| {}).ok();
                return Ok(Flow::Continue);
            }
            let Some(frame) = frames.receive_latest()? else {
                return Ok(Flow::Continue);
            };
            let id = (frame.header.msg_seq, frame.header.capture_ns);
            if last_frame == Some(id) {
                return Ok(Flow::Continue);
            }
            last_frame = Some(id);
            last_view_ns = now_ns;
            let started_ns = now_ns;
            downscale_rgb(&frame.rgb, RGB_WIDTH_PX, scale, (width, height), &mut small);
            // The frame goes back to the camera's pool before the (longer) encoding.
            drop(frame);
            if let Err(error) = encode_jpeg(
                &small,
                width as u32,
                height as u32,
                settings.jpeg_quality,
                &mut jpeg,
            ) {
                tracing::warn!(%error, "camera view not encoded");
                return Ok(Flow::Continue);
            }
            let encoded_ns = MonotonicClock::read_ns();
            view.work_ns
                .fetch_add(encoded_ns.saturating_sub(started_ns), Ordering::Relaxed);
            view_seq += 1;
            view.publish(EncodedFrame {
                jpeg: Arc::from(jpeg.as_slice()),
                view_seq,
                frame_seq: id.0,
                capture_ns: id.1,
                encoded_ns,
                width_px: width as u32,
                height_px: height as u32,
                scale: scale as u32,
            });
            tracing::trace!(view_seq, bytes = jpeg.len(), "camera view encoded");
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_box_filter_averages_blocks() {
        // 4x2 image, factor 2 -> 2x1.
        let src: Vec<u8> = [
            [0u8, 0, 0],
            [10, 20, 30],
            [100, 100, 100],
            [200, 200, 200],
            [0, 0, 0],
            [10, 20, 30],
            [100, 100, 100],
            [200, 200, 200],
        ]
        .concat();
        let mut out = Vec::new();
        downscale_rgb(&src, 4, 2, (2, 1), &mut out);
        assert_eq!(out, vec![5, 10, 15, 150, 150, 150]);
    }

    #[test]
    fn a_view_encodes_as_jpeg_and_waiters_see_the_newer_one() {
        let rgb = vec![128u8; 64 * 32 * 3];
        let mut jpeg = Vec::new();
        encode_jpeg(&rgb, 64, 32, 70, &mut jpeg).expect("encode");
        assert_eq!(&jpeg[..2], &[0xff, 0xd8]);
        let view = CameraView::default();
        assert!(view.wait_newer(0, Duration::from_millis(1)).is_none());
        view.publish(EncodedFrame {
            jpeg: Arc::from(jpeg.as_slice()),
            view_seq: 1,
            frame_seq: 7,
            capture_ns: 9,
            encoded_ns: 10,
            width_px: 64,
            height_px: 32,
            scale: 1,
        });
        assert_eq!(
            view.wait_newer(0, Duration::from_millis(1))
                .map(|f| f.view_seq),
            Some(1)
        );
        // Nothing newer than 1: the wait times out and returns the newest.
        assert_eq!(
            view.wait_newer(1, Duration::from_millis(5))
                .map(|f| f.view_seq),
            Some(1)
        );
    }
}
