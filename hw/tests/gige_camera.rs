//! The GigE Vision driver against Aravis's fake GigE Vision camera on loopback (GVCP/GVSP over
//! UDP, hosted in this process): the camera trait's conformance suite, the pixel formats
//! converted as the fake sent them, and lost frames counted. Aravis is required (`.ci/run`
//! installs it): without it the tests fail, naming the package.

use harvest_aravis::{Aravis, FakeCamera, LoopbackCameraLock};
use harvest_hw::conformance::TestWatchdog;
use harvest_hw::rgbd_camera::RgbdCamera;
use harvest_hw::rgbd_camera::conformance::{CameraConformanceConfig, conformance_suite};
use harvest_hw::rgbd_camera::gige::{GigeCamera, GigeConfig, PixelFormat};
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::payload::boxed_zeroed;
use harvest_ipc::payloads::RgbdFrame;
use std::cell::RefCell;
use std::time::Duration;

const WATCHDOG: Duration = Duration::from_secs(120);

fn config(pixel_format: PixelFormat) -> GigeConfig {
    GigeConfig {
        camera_id: Some("127.0.0.1".into()),
        pixel_format,
        frame_rate_hz: 30.0,
        exposure_us: Some(4000.0),
        packet_size_bytes: Some(8000),
        region_offset_px: None,
        buffers: 4,
        intrinsics: CameraIntrinsics::tl460_rgb(),
    }
}

#[test]
fn the_gige_driver_passes_the_camera_conformance_suite_against_the_fake() {
    // Aravis is required (`.ci/run` installs it): its error names the package to install.
    let aravis = Aravis::load().unwrap_or_else(|error| panic!("{error}"));
    let _watchdog = TestWatchdog::arm("gige conformance", WATCHDOG);
    let _lock = LoopbackCameraLock::acquire().unwrap();
    let fake = RefCell::new(FakeCamera::start(&aravis, "127.0.0.1", "HVCONF").unwrap());
    for format in [PixelFormat::BayerRG8, PixelFormat::Mono8, PixelFormat::RGB8] {
        fake.borrow_mut().set_lost_packet_ratio(0.0);
        let config = config(format);
        let report = conformance_suite(
            &CameraConformanceConfig::color_only(config.intrinsics),
            || GigeCamera::open_with(&aravis, &config, None).unwrap(),
            || {
                // The silent camera: the link drops every packet, so no frame ever completes.
                fake.borrow_mut().set_lost_packet_ratio(1.0);
                GigeCamera::open_with(&aravis, &config, None).unwrap()
            },
        )
        .unwrap_or_else(|error| panic!("{format:?}: {error}"));
        assert_eq!(report.checks_passed.len(), 3, "{format:?}: {report:?}");
    }
}

#[test]
fn bayer_frames_are_demosaiced_and_lost_packets_cost_counted_frames() {
    // Aravis is required (`.ci/run` installs it): its error names the package to install.
    let aravis = Aravis::load().unwrap_or_else(|error| panic!("{error}"));
    let _watchdog = TestWatchdog::arm("gige formats", WATCHDOG);
    let _lock = LoopbackCameraLock::acquire().unwrap();
    let mut fake = FakeCamera::start(&aravis, "127.0.0.1", "HVFMT").unwrap();
    // A flat orange in the camera's mosaic (RG/GB): every demosaiced pixel is that orange.
    const ORANGE: [u8; 3] = [230, 120, 20];
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
    let mut camera = GigeCamera::open_with(&aravis, &config(PixelFormat::BayerRG8), None).unwrap();
    let mut frame: Box<RgbdFrame> = boxed_zeroed();
    let mut captured = 0;
    while captured < 3 {
        if camera
            .capture_into(&mut frame, Duration::from_secs(5))
            .unwrap()
        {
            captured += 1;
        }
    }
    assert!(frame.meta.is_color_only());
    assert_eq!(frame.meta.exposure_us, 4000);
    assert!(frame.rgb.chunks_exact(3).all(|pixel| pixel == ORANGE));
    let health = camera.health();
    assert_eq!((health.frames, health.lost_frames), (3, 0), "{health:?}");

    // 0.2 % of the packets lost: the fake does not resend, so the frames they belonged to are
    // lost, counted, and never delivered.
    fake.set_lost_packet_ratio(0.002);
    let mut delivered = 0;
    while delivered < 10 {
        if camera
            .capture_into(&mut frame, Duration::from_secs(5))
            .unwrap()
        {
            delivered += 1;
            assert!(frame.rgb.chunks_exact(3).all(|pixel| pixel == ORANGE));
        }
    }
    let health = camera.health();
    assert!(health.lost_frames > 0, "{health:?}");
    assert!(health.missing_packets > 0, "{health:?}");
}
