//! Camera frames on a thread of their own: its own iceoryx2 node and wait set on `camera/rgbd`
//! (a one-slot buffer: only the newest frame matters), the frame read in place from shared
//! memory, downscaled and JPEG-encoded at the viewing rate, and only while a client is
//! subscribed to `/camera/image`. A slow encoder costs frames of this view, never the stack:
//! the channel's safe overflow drops what this subscriber does not take.

use crate::server::LiveChannels;
use harvest_foxglove_mapping::topics;
use harvest_foxglove_mapping::{CameraMapper, JpegEncoder, RateLimit};
use harvest_ipc::catalogue::CAMERA_RGBD;
use harvest_ipc::{Context, Domain, Flow, MonotonicClock, Waiter};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How often the thread checks its stop flag without frames.
const STOP_CHECK: Duration = Duration::from_millis(200);

/// What the camera thread did, readable while it runs.
#[derive(Debug, Default)]
pub struct CameraCounters {
    /// Frames taken from the channel.
    pub received: AtomicU64,
    /// Images encoded and sent.
    pub sent: AtomicU64,
    /// Frames that could not be encoded.
    pub failed: AtomicU64,
    /// Time spent downscaling and encoding the last image, microseconds.
    pub last_encode_us: AtomicU64,
}

/// The running camera thread.
pub struct CameraThread {
    pub counters: Arc<CameraCounters>,
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Result<(), String>>,
}

/// Everything the thread needs, moved into it.
pub struct CameraSetup {
    pub domain: Domain,
    pub node_name: String,
    pub mapper: CameraMapper,
    pub encoder: JpegEncoder,
    pub limit: RateLimit,
    pub channels: LiveChannels,
}

impl CameraThread {
    pub fn spawn(setup: CameraSetup) -> std::io::Result<Self> {
        let counters = Arc::new(CameraCounters::default());
        let stop = Arc::new(AtomicBool::new(false));
        let thread_counters = counters.clone();
        let thread_stop = stop.clone();
        let thread = std::thread::Builder::new()
            .name("foxglove-camera".to_owned())
            .spawn(move || run(setup, &thread_counters, &thread_stop))?;
        Ok(Self {
            counters,
            stop,
            thread,
        })
    }

    /// True when the thread ended (an error, or a termination signal it saw first).
    pub fn is_finished(&self) -> bool {
        self.thread.is_finished()
    }

    /// Stops the thread and returns its error, if it had one.
    pub fn stop(self) -> Result<(), String> {
        self.stop.store(true, Ordering::SeqCst);
        self.thread
            .join()
            .unwrap_or_else(|_| Err("the camera thread panicked".to_owned()))
    }
}

fn run(mut setup: CameraSetup, counters: &CameraCounters, stop: &AtomicBool) -> Result<(), String> {
    let context =
        Context::new(&setup.domain, &setup.node_name).map_err(|error| error.to_string())?;
    let frames = context
        .subscriber_with_buffer(CAMERA_RGBD, 1)
        .map_err(|error| error.to_string())?;
    let waiter = Waiter::new().map_err(|error| error.to_string())?;
    let _frames_guard = waiter
        .attach_listener(frames.listener())
        .map_err(|error| error.to_string())?;
    let _tick = waiter
        .attach_interval(STOP_CHECK)
        .map_err(|error| error.to_string())?;
    let result = waiter.run(|_| -> Result<Flow, String> {
        if let Some(frame) = frames.receive_latest().map_err(|error| error.to_string())? {
            counters.received.fetch_add(1, Ordering::Relaxed);
            let now_ns = MonotonicClock::read_ns();
            if setup.channels.watched(topics::CAMERA_IMAGE) && setup.limit.admit(now_ns) {
                let started = Instant::now();
                match setup.encoder.encode(&frame) {
                    Ok(jpeg) => {
                        counters
                            .last_encode_us
                            .store(started.elapsed().as_micros() as u64, Ordering::Relaxed);
                        // The live sink cannot fail (a slow client drops messages instead).
                        let _ = setup
                            .mapper
                            .write(&frame, jpeg, now_ns, &mut setup.channels);
                        counters.sent.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(error) => {
                        if counters.failed.fetch_add(1, Ordering::Relaxed) == 0 {
                            tracing::warn!(%error, "cannot encode a camera image");
                        }
                    }
                }
            }
        }
        Ok(if stop.load(Ordering::SeqCst) {
            Flow::Stop
        } else {
            Flow::Continue
        })
    });
    match result {
        Ok(_) => Ok(()),
        Err(error) => Err(format!("camera thread: {}", error.flatten_text())),
    }
}

/// Text of a wait-set run error with a `String` callback error.
trait FlattenText {
    fn flatten_text(self) -> String;
}

impl FlattenText for harvest_ipc::RunError<String> {
    fn flatten_text(self) -> String {
        match self {
            Self::Wait(error) => error.to_string(),
            Self::Callback(error) => error,
        }
    }
}
