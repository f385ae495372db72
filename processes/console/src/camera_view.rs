//! The camera view: on a thread of its own, at its own rate, the newest `camera/rgbd` frame is
//! read in place in shared memory, box-filtered down to the view size, released, and encoded
//! as JPEG. The thread wakes on the camera's frame event and encodes a frame when at least one
//! view period has passed since the last view (so a view waits for no timer after its frame
//! arrives); a timer at the view rate catches a frame whose event came too early. The camera never waits for it: the channel drops the oldest frame for a subscriber
//! that is behind (safe overflow), and this subscriber keeps a one-frame buffer.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use bytes::Bytes;
use tokio::sync::watch;

use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};
use harvest_ipc::{Context, Domain, Flow, MonotonicClock, Waiter};
use harvest_perception::downscale::downscale_rgb;
use image::ImageEncoder;

use crate::error::ConsoleError;

/// One encoded view.
#[derive(Debug, Clone, PartialEq)]
pub struct EncodedFrame {
    /// The view as it is pushed to the pages ([`push_message`]): the header, then the JPEG.
    pub message: Bytes,
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
    /// Where the JPEG starts in `message`.
    jpeg_offset: usize,
}

impl EncodedFrame {
    /// Builds the frame around `jpeg` (one copy, into the pushed message).
    pub fn new(
        jpeg: &[u8],
        view_seq: u64,
        frame_seq: u64,
        capture_ns: u64,
        encoded_ns: u64,
        (width_px, height_px): (u32, u32),
        scale: u32,
    ) -> Self {
        let header = serde_json::json!({
            "view_seq": view_seq,
            "frame_seq": frame_seq,
            "capture_ns": capture_ns,
            "encoded_ns": encoded_ns,
            "width_px": width_px,
            "height_px": height_px,
            "scale": scale,
        })
        .to_string();
        let (message, jpeg_offset) = push_message(header.as_bytes(), jpeg);
        Self {
            message,
            view_seq,
            frame_seq,
            capture_ns,
            encoded_ns,
            width_px,
            height_px,
            scale,
            jpeg_offset,
        }
    }

    /// The JPEG (shares the message's bytes).
    pub fn jpeg(&self) -> Bytes {
        self.message.slice(self.jpeg_offset..)
    }
}

/// A pushed view: the header's length (u32, little-endian), the header (JSON), the JPEG.
/// Returns the message and where the JPEG starts.
pub fn push_message(header: &[u8], jpeg: &[u8]) -> (Bytes, usize) {
    let mut message = Vec::with_capacity(4 + header.len() + jpeg.len());
    message.extend_from_slice(&(header.len() as u32).to_le_bytes());
    message.extend_from_slice(header);
    let offset = message.len();
    message.extend_from_slice(jpeg);
    (Bytes::from(message), offset)
}

/// The newest view, shared with the server: each page's push connection watches it and
/// sends the newest one when it can (a slow page skips views; nothing queues).
#[derive(Debug)]
pub struct CameraView {
    latest: watch::Sender<Option<Arc<EncodedFrame>>>,
    /// Time spent downscaling and encoding, ns (for the status panel).
    pub work_ns: AtomicU64,
}

impl Default for CameraView {
    fn default() -> Self {
        Self {
            latest: watch::Sender::new(None),
            work_ns: AtomicU64::new(0),
        }
    }
}

impl CameraView {
    /// The newest view.
    pub fn latest(&self) -> Option<Arc<EncodedFrame>> {
        self.latest.borrow().clone()
    }

    /// A receiver that sees each newer view (only the newest one when several came in between).
    pub fn subscribe(&self) -> watch::Receiver<Option<Arc<EncodedFrame>>> {
        self.latest.subscribe()
    }

    /// Makes `frame` the newest view.
    pub fn publish(&self, frame: EncodedFrame) {
        self.latest.send_replace(Some(Arc::new(frame)));
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
            view.publish(EncodedFrame::new(
                &jpeg,
                view_seq,
                id.0,
                id.1,
                encoded_ns,
                (width as u32, height as u32),
                scale as u32,
            ));
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
    fn a_view_encodes_as_jpeg_and_watchers_see_only_the_newest() {
        let rgb = vec![128u8; 64 * 32 * 3];
        let mut jpeg = Vec::new();
        encode_jpeg(&rgb, 64, 32, 70, &mut jpeg).expect("encode");
        assert_eq!(&jpeg[..2], &[0xff, 0xd8]);
        let view = CameraView::default();
        let mut watcher = view.subscribe();
        assert!(view.latest().is_none());
        for seq in 1..=3 {
            view.publish(EncodedFrame::new(&jpeg, seq, 7 + seq, 9, 10, (64, 32), 1));
        }
        // Three views published, one change seen: the newest.
        assert!(watcher.has_changed().expect("open"));
        let seen = watcher.borrow_and_update().clone().expect("a view");
        assert_eq!(seen.view_seq, 3);
        assert!(!watcher.has_changed().expect("open"));
        // The pushed message: header length, JSON header, the JPEG.
        let message = &seen.message;
        let length = u32::from_le_bytes(message[..4].try_into().expect("4 bytes")) as usize;
        let header: serde_json::Value =
            serde_json::from_slice(&message[4..4 + length]).expect("json header");
        assert_eq!(header["view_seq"], 3);
        assert_eq!(header["frame_seq"], 10);
        assert_eq!(&message[4 + length..], &jpeg[..]);
        assert_eq!(&seen.jpeg()[..], &jpeg[..]);
    }
}
