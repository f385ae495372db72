//! `harvest camera --device gige` as its own process against Aravis's fake GigE Vision camera
//! (GVCP/GVSP over UDP on loopback, served from this test process), over real shared memory:
//! frames on `camera/rgbd` flagged colour only, with no depth, the fake's image demosaiced into
//! their colour, stamps that advance, a running heartbeat and a clean stop on SIGINT. A config
//! file with an unknown key or an unusable value stops the process before it opens a camera,
//! naming the file, the key and the line or value. The camera tests require Aravis (`.ci/run`
//! installs it; without it they fail naming the package); one fake at a time serves on
//! 127.0.0.1 (`LoopbackCameraLock`, held across processes).

mod common;

use common::*;
use harvest_aravis::{Aravis, FakeCamera, LoopbackCameraLock};
use harvest_hw::conformance::TestWatchdog;
use harvest_ipc::Context;
use harvest_ipc::catalogue::{CAMERA_RGBD, PROCESS_HEALTH};
use harvest_ipc::payloads::rgbd_frame::{RGB_HEIGHT_PX, RGB_WIDTH_PX};
use harvest_ipc::payloads::{ProcessRunState, RgbdFrameMeta};
use std::time::{Duration, Instant};

const GIGE_CONFIG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sim/gige_camera.toml");

/// A flat orange in the fake's RG/GB Bayer mosaic: every demosaiced pixel is this orange.
const ORANGE: [u8; 3] = [230, 120, 20];

#[test]
fn harvest_camera_publishes_the_fake_gige_cameras_frames_as_colour_only() {
    // Aravis is required (`.ci/run` installs it): its error names the package to install.
    let aravis = Aravis::load().unwrap_or_else(|error| panic!("{error}"));
    let _watchdog = TestWatchdog::arm("gige camera process", Duration::from_secs(120));
    let _lock = LoopbackCameraLock::acquire().expect("loopback camera lock");
    let mut fake = FakeCamera::start(&aravis, "127.0.0.1", "HVPROC").expect("fake camera");
    fake.set_fill(|image| {
        let width = image.width as usize;
        for (index, sample) in image.data.iter_mut().enumerate() {
            let (x, y) = (index % width, index / width);
            *sample = match (y % 2, x % 2) {
                (0, 0) => ORANGE[0],
                (1, 1) => ORANGE[2],
                _ => ORANGE[1],
            };
        }
    });
    let domain = unique_domain("gigeproc");
    let context = Context::new(domain.domain(), "gige-test").expect("node");
    let frames = context
        .subscriber_with_buffer(CAMERA_RGBD, 3)
        .expect("frames");
    let health = context.subscriber(PROCESS_HEALTH).expect("health");
    let camera = Drained::spawn(
        &domain,
        &[
            "camera",
            "--device",
            "gige",
            "--config",
            GIGE_CONFIG,
            "--camera-id",
            "127.0.0.1",
        ],
    );

    // Ten frames, checked as they arrive.
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut received = 0;
    let (mut last_seq, mut last_capture_ns) = (0u64, 0u64);
    while received < 10 {
        assert!(Instant::now() < deadline, "{received} frames within 60 s");
        while let Some(frame) = frames.receive().expect("receive frame") {
            let meta = &frame.meta;
            assert!(meta.is_color_only(), "flags {:#x}", meta.flags);
            assert_eq!(meta.flags & RgbdFrameMeta::FLAG_COLOR_ONLY, 2);
            assert_eq!(
                (meta.rgb_intrinsics.width_px, meta.rgb_intrinsics.height_px),
                (RGB_WIDTH_PX as u32, RGB_HEIGHT_PX as u32)
            );
            assert!(frame.depth_mm.iter().all(|&depth| depth == 0));
            // The centre pixel and one near a corner (away from the border's demosaicing).
            for (x, y) in [(RGB_WIDTH_PX / 2, RGB_HEIGHT_PX / 2), (10, 10)] {
                let at = (y * RGB_WIDTH_PX + x) * 3;
                assert_eq!(frame.rgb[at..at + 3], ORANGE, "pixel ({x}, {y})");
            }
            assert!(frame.header.msg_seq > last_seq);
            assert!(frame.header.capture_ns > last_capture_ns);
            assert!(frame.header.capture_ns <= frame.header.publish_ns);
            (last_seq, last_capture_ns) = (frame.header.msg_seq, frame.header.capture_ns);
            received += 1;
        }
        let _ = frames
            .listener()
            .timed_wait(|_| {}, Duration::from_millis(100));
    }

    // The heartbeat: running, nothing lost on loopback.
    let deadline = Instant::now() + Duration::from_secs(10);
    let beat = 'beat: loop {
        while let Some(beat) = health.receive().expect("receive health") {
            if beat.process_name.as_str() == "camera"
                && matches!(beat.run_state.get(), Ok(ProcessRunState::Running))
            {
                break 'beat *beat;
            }
        }
        assert!(Instant::now() < deadline, "no running camera heartbeat");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert_eq!(
        (beat.detail.as_str(), beat.detail_value),
        ("device_errors", 0),
        "{beat:?}"
    );

    let (status, _, stderr) = camera.interrupt_and_wait(Duration::from_secs(15));
    assert!(status.success(), "harvest camera failed:\n{stderr}");
    assert!(stderr.contains("camera stopped"), "{stderr}");
    drop(fake);
}

#[test]
fn a_bad_gige_config_stops_harvest_camera_naming_the_key() {
    let _watchdog = TestWatchdog::arm("gige config errors", Duration::from_secs(60));
    let dir = TempDir::new("gigecfg");
    let good = std::fs::read_to_string(GIGE_CONFIG).expect("read sim/gige_camera.toml");

    // An unknown key (a misspelt one): the file, its line and the key.
    let misspelt = good.replace("exposure_us = 10000.0", "exposure_ms = 10.0");
    let line = misspelt
        .lines()
        .position(|line| line.starts_with("exposure_ms"))
        .expect("the misspelt key")
        + 1;
    let path = dir.write("misspelt.toml", &misspelt);
    let domain = unique_domain("gigecfg1");
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "camera",
            "--device",
            "gige",
            "--config",
            path.to_str().expect("utf-8 path"),
        ],
        Duration::from_secs(30),
    );
    assert!(!status.success(), "{stderr}");
    assert!(stderr.contains("misspelt.toml"), "{stderr}");
    assert!(stderr.contains(&format!("line {line}")), "{stderr}");
    assert!(stderr.contains("exposure_ms"), "{stderr}");

    // A value out of range: the file, the key and the value.
    let path = dir.write(
        "rate.toml",
        &good.replace("frame_rate_hz = 30.0", "frame_rate_hz = -30.0"),
    );
    let domain = unique_domain("gigecfg2");
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "camera",
            "--device",
            "gige",
            "--config",
            path.to_str().expect("utf-8 path"),
        ],
        Duration::from_secs(30),
    );
    assert!(!status.success(), "{stderr}");
    assert!(stderr.contains("rate.toml"), "{stderr}");
    assert!(stderr.contains("frame_rate_hz = -30"), "{stderr}");

    // No config at all.
    let domain = unique_domain("gigecfg3");
    let (status, _, stderr) = run_harvest(
        &domain,
        &["camera", "--device", "gige"],
        Duration::from_secs(30),
    );
    assert!(!status.success(), "{stderr}");
    assert!(
        stderr.contains("--device gige needs --config FILE"),
        "{stderr}"
    );
}
