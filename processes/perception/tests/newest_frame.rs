//! Frames never queue behind a slow detector: the `perception` process loop
//! (`process::run_until`) on a thread with a detector double that takes 300 ms a frame, the test
//! acting as the camera on `camera/rgbd` (real iceoryx2 shared memory, loaned 6.8 MB frames).
//!
//! The test publishes the first frame, waits until the detector is working on it, and publishes
//! the rest of a burst while the detector is held on that first frame. Checks: perception then
//! works on the newest frame, not on the ones that queued (exactly the first and the last frame
//! are processed, the rest are skipped: a gap in the detections' `source_frame_seq`), the
//! detections carry their frame's capture stamp, and the heartbeat reports the processed frame's
//! age (`frame_age_ns`: at least the time the newest frame waited behind the first).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{CAMERA_RGBD, PERCEPTION_APPLES, PROCESS_HEALTH};
use harvest_ipc::payloads::{AppleDetections, ProcessHealth, RgbdFrameMeta};
use harvest_ipc::{Context, MonotonicClock, Payload, ScratchDomain, Subscriber};
use harvest_perception::detector::{Detection, Detector, DetectorFrameInfo};
use harvest_perception::{FrameError, RgbView};
use harvest_perception_process::process::{PerceptionArgs, run_until};

/// Watchdog on every wait of the test.
const WATCHDOG: Duration = Duration::from_secs(60);
/// The detector double's time per frame (nine camera frames at 30 Hz).
const DETECT_TIME: Duration = Duration::from_millis(300);
/// Frames in the burst.
const BURST: u64 = 30;

/// A detector that finds nothing and takes [`DETECT_TIME`] to do it (a large model on a CPU).
/// On its first frame it also waits for the test's word (`release`), so the burst is published
/// while it is busy whatever the machine's load.
struct SlowDetector {
    started: Arc<AtomicU64>,
    calls: Arc<AtomicU64>,
    release: Mutex<mpsc::Receiver<()>>,
}

impl Detector for SlowDetector {
    fn name(&self) -> &'static str {
        "slow double"
    }

    fn detect(
        &mut self,
        _rgb: &RgbView<'_>,
        detections: &mut Vec<Detection>,
    ) -> Result<DetectorFrameInfo, FrameError> {
        if self.started.fetch_add(1, Ordering::SeqCst) == 0 {
            let release = self.release.lock().expect("release lock");
            release
                .recv_timeout(WATCHDOG)
                .expect("the test releases the first frame");
        }
        std::thread::sleep(DETECT_TIME);
        self.calls.fetch_add(1, Ordering::SeqCst);
        detections.clear();
        Ok(DetectorFrameInfo::default())
    }
}

/// Waits (event-driven, bounded by the watchdog) for the first message `accept` takes; every
/// message read is appended to `seen`.
fn wait_for<T: Payload + Copy>(
    subscriber: &Subscriber<T>,
    seen: &mut Vec<T>,
    accept: impl Fn(&T) -> bool,
) -> T {
    let deadline = Instant::now() + WATCHDOG;
    loop {
        while let Some(message) = subscriber.receive().expect("receive") {
            seen.push(*message);
            if accept(&message) {
                return *message;
            }
        }
        let remaining = deadline.saturating_duration_since(Instant::now());
        assert!(
            !remaining.is_zero(),
            "watchdog: nothing on {:?}",
            subscriber.channel()
        );
        let _ = subscriber.listener().timed_wait(|_| {}, remaining);
    }
}

#[test]
fn a_slow_detector_works_on_the_newest_frame_and_skips_the_rest() {
    let domain = ScratchDomain::new("newest");
    let stop = Arc::new(AtomicBool::new(false));
    let started = Arc::new(AtomicU64::new(0));
    let calls = Arc::new(AtomicU64::new(0));
    let (release, release_rx) = mpsc::channel();
    let perception = {
        let (domain, stop, started, calls) = (
            domain.clone(),
            Arc::clone(&stop),
            Arc::clone(&started),
            Arc::clone(&calls),
        );
        std::thread::spawn(move || {
            let args = PerceptionArgs {
                calibration: Some(
                    concat!(
                        env!("CARGO_MANIFEST_DIR"),
                        "/../../sim/camera_calibration.toml"
                    )
                    .into(),
                ),
                config: None,
                estimator: None,
                detector: None,
                model: None,
                no_laser: true,
                laser_calibration: None,
                depth_source: None,
                lidar_extrinsic: None,
            };
            let detector = Box::new(SlowDetector {
                started,
                calls,
                release: Mutex::new(release_rx),
            });
            run_until(&args, &domain, "perception", Some(detector), &stop)
                .map_err(|e| e.to_string())
        })
    };

    let context = Context::new(&domain, "camera_test").expect("context");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let mut frames = context.publisher(CAMERA_RGBD).expect("frames");
    let detections = context.subscriber(PERCEPTION_APPLES).expect("detections");
    let mut beats: Vec<ProcessHealth> = Vec::new();
    // The first heartbeat comes from the running loop: its frame subscriber exists by then.
    wait_for(&health, &mut beats, |beat| {
        beat.process_name.as_str() == "perception"
    });

    // The burst: frame 1 wakes perception; the others are published once its detector is busy
    // with it.
    let mut capture_ns_by_seq = vec![0u64; BURST as usize + 1];
    let mut publish = |capture_ns_by_seq: &mut Vec<u64>| {
        let capture_ns = MonotonicClock::read_ns();
        let seq = frames
            .publish_with(capture_ns, |frame| frame.meta = RgbdFrameMeta::default())
            .expect("publish frame");
        capture_ns_by_seq[seq as usize] = capture_ns;
    };
    publish(&mut capture_ns_by_seq);
    let deadline = Instant::now() + WATCHDOG;
    while started.load(Ordering::SeqCst) == 0 {
        assert!(
            Instant::now() < deadline,
            "watchdog: the detector never started"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    for _ in 1..BURST {
        publish(&mut capture_ns_by_seq);
    }
    release.send(()).expect("release the first frame");
    let mut outputs: Vec<AppleDetections> = Vec::new();
    wait_for(&detections, &mut outputs, |out| {
        out.source_frame_seq == BURST
    });

    // The first frame and the newest were worked on; a queue would have worked on all 30, one
    // after the other. The others were skipped (the gap in `source_frame_seq`).
    let processed: Vec<u64> = outputs.iter().map(|out| out.source_frame_seq).collect();
    assert_eq!(processed, vec![1, BURST]);
    assert_eq!(calls.load(Ordering::SeqCst), processed.len() as u64);
    for out in &outputs {
        assert_eq!(
            out.source_capture_ns, capture_ns_by_seq[out.source_frame_seq as usize],
            "{out:?}"
        );
    }
    // A heartbeat after the newest frame was processed reports that frame's age: at least the
    // first frame's detection it waited behind, less than its age at the heartbeat.
    let newest_capture_ns = capture_ns_by_seq[BURST as usize];
    let beat = wait_for(&health, &mut beats, |beat| {
        beat.process_name.as_str() == "perception"
            && beat.detail.as_str() == "frame_age_ns"
            && beat.header.publish_ns > newest_capture_ns + 2 * DETECT_TIME.as_nanos() as u64
    });
    assert!(
        beat.detail_value >= DETECT_TIME.as_nanos() as u64,
        "{beat:?}"
    );
    assert!(
        beat.detail_value < beat.header.publish_ns - newest_capture_ns,
        "{beat:?}"
    );

    stop.store(true, Ordering::SeqCst);
    perception
        .join()
        .expect("perception thread")
        .expect("perception loop ends cleanly");
}
