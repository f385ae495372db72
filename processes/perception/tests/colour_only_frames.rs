//! Colour-only frames (a GigE Vision camera: `RgbdFrameMeta::FLAG_COLOR_ONLY`, no depth of its
//! own) reaching the `perception` process loop (`process::run_until` on a thread), the test
//! acting as the camera on `camera/rgbd` over real iceoryx2 shared memory.
//!
//! - With the ToF depth source nothing will ever give such a frame depth: the loop ends at the
//!   first one with an error that names the fix (the LiDAR-fused source).
//! - With the LiDAR-fused source and no cloud fused yet, the frames are refused but the process
//!   goes on: each frame still gets its (empty) detections, and the heartbeat is degraded.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use harvest_ipc::catalogue::{CAMERA_RGBD, PERCEPTION_APPLES, PROCESS_HEALTH};
use harvest_ipc::payloads::{ProcessRunState, RgbdFrameMeta};
use harvest_ipc::{Context, MonotonicClock, Publisher, ScratchDomain};
use harvest_perception::depth_source::DepthSource;
use harvest_perception_process::process::{PerceptionArgs, run_until};

/// Watchdog on every wait of the test.
const WATCHDOG: Duration = Duration::from_secs(60);

fn sim_file(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../sim")
        .join(name)
}

/// `run_until` on a thread with `depth_source`; the segmentation detector.
fn start(
    domain: &ScratchDomain,
    stop: &Arc<AtomicBool>,
    depth_source: DepthSource,
) -> JoinHandle<Result<(), String>> {
    let args = PerceptionArgs {
        calibration: Some(sim_file("camera_calibration.toml")),
        config: None,
        estimator: None,
        detector: None,
        model: None,
        no_laser: true,
        laser_calibration: None,
        depth_source: Some(depth_source),
        lidar_extrinsic: match depth_source {
            DepthSource::Tof => None,
            DepthSource::LidarFused => Some(sim_file("lidar_extrinsic.toml")),
        },
    };
    let (domain, stop) = (harvest_ipc::Domain::clone(domain), Arc::clone(stop));
    std::thread::spawn(move || {
        run_until(&args, &domain, "perception", None, &stop).map_err(|error| error.to_string())
    })
}

/// Waits for perception's first heartbeat (its frame subscriber exists by then).
fn wait_until_running(context: &Context) {
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let deadline = Instant::now() + WATCHDOG;
    loop {
        while let Some(beat) = health.receive().expect("receive health") {
            if beat.process_name.as_str() == "perception" {
                return;
            }
        }
        assert!(
            Instant::now() < deadline,
            "watchdog: no perception heartbeat"
        );
        let _ = health
            .listener()
            .timed_wait(|_| {}, Duration::from_millis(100));
    }
}

/// Publishes one colour-only frame (the GigE camera's geometry: depth all 0); its `msg_seq`.
fn publish_colour_only(frames: &mut Publisher<harvest_ipc::payloads::RgbdFrame>) -> u64 {
    frames
        .publish_with(MonotonicClock::read_ns(), |frame| {
            frame.meta = RgbdFrameMeta {
                flags: RgbdFrameMeta::FLAG_COLOR_ONLY,
                ..RgbdFrameMeta::default()
            };
            frame.depth_mm.fill(0);
        })
        .expect("publish frame")
}

#[test]
fn with_the_tof_depth_source_a_colour_only_frame_stops_perception_naming_the_fix() {
    let domain = ScratchDomain::new("colour-tof");
    let stop = Arc::new(AtomicBool::new(false));
    let perception = start(&domain, &stop, DepthSource::Tof);
    let context = Context::new(&domain, "camera_test").expect("context");
    wait_until_running(&context);
    let mut frames = context.publisher(CAMERA_RGBD).expect("frames");
    let seq = publish_colour_only(&mut frames);

    let deadline = Instant::now() + WATCHDOG;
    while !perception.is_finished() {
        assert!(Instant::now() < deadline, "watchdog: perception still runs");
        std::thread::sleep(Duration::from_millis(20));
    }
    stop.store(true, Ordering::SeqCst);
    let error = perception
        .join()
        .expect("perception thread")
        .expect_err("perception must stop on a colour-only frame with the ToF depth source");
    assert!(
        error.contains(&format!("frame {seq} is colour only")),
        "{error}"
    );
    assert!(error.contains("--depth-source lidar-fused"), "{error}");
    assert!(error.contains("ToF depth source"), "{error}");
}

#[test]
fn with_the_fused_source_colour_only_frames_wait_for_the_first_cloud() {
    let domain = ScratchDomain::new("colour-fused");
    let stop = Arc::new(AtomicBool::new(false));
    let perception = start(&domain, &stop, DepthSource::LidarFused);
    let context = Context::new(&domain, "camera_test").expect("context");
    let detections = context.subscriber(PERCEPTION_APPLES).expect("detections");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    wait_until_running(&context);
    let mut frames = context.publisher(CAMERA_RGBD).expect("frames");

    // Three frames, one at a time: each gets its detections (none: no depth to localize from).
    for _ in 0..3 {
        let seq = publish_colour_only(&mut frames);
        let deadline = Instant::now() + WATCHDOG;
        'answer: loop {
            while let Some(out) = detections.receive().expect("receive detections") {
                if out.source_frame_seq == seq {
                    assert_eq!(out.apples.len(), 0, "frame {seq}");
                    break 'answer;
                }
            }
            assert!(!perception.is_finished(), "perception ended on frame {seq}");
            assert!(
                Instant::now() < deadline,
                "watchdog: frame {seq} unanswered"
            );
            let _ = detections
                .listener()
                .timed_wait(|_| {}, Duration::from_millis(100));
        }
    }

    // Every frame refused: the heartbeat says degraded.
    let deadline = Instant::now() + WATCHDOG;
    'degraded: loop {
        while let Some(beat) = health.receive().expect("receive health") {
            if beat.process_name.as_str() == "perception"
                && matches!(beat.run_state.get(), Ok(ProcessRunState::Degraded))
            {
                break 'degraded;
            }
        }
        assert!(Instant::now() < deadline, "watchdog: no degraded heartbeat");
        let _ = health
            .listener()
            .timed_wait(|_| {}, Duration::from_millis(100));
    }

    stop.store(true, Ordering::SeqCst);
    perception
        .join()
        .expect("perception thread")
        .expect("perception loop ends cleanly");
}
