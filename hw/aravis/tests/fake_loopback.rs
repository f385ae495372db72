//! The safe types against Aravis's own fake GigE Vision camera on loopback: the camera is
//! opened by address, configured, streams complete 1920x1080 frames, and the images are the
//! ones the fill function wrote. Aravis is required (`.ci/run` installs it): without
//! it the tests fail, naming the package.

use harvest_aravis::pixel_format::{MONO_8, RGB_8};
use harvest_aravis::{Aravis, AravisError, BufferStatus, Camera, FakeCamera, LoopbackCameraLock};
use std::time::Duration;

#[test]
fn a_filled_fake_streams_its_images_to_a_camera_opened_by_address() {
    // Aravis is required (`.ci/run` installs it): its error names the package to install.
    let aravis = Aravis::load().unwrap_or_else(|error| panic!("{error}"));
    let _lock = LoopbackCameraLock::acquire().unwrap();
    let mut fake = FakeCamera::start(&aravis, "127.0.0.1", "HV01").unwrap();
    fake.set_fill(|image| {
        let stamp = (image.frame_id % 200) as u8;
        for (index, byte) in image.data.iter_mut().enumerate() {
            *byte = if index < 16 {
                stamp
            } else {
                (index % 251) as u8
            };
        }
    });
    let mut camera = Camera::open(&aravis, Some("127.0.0.1")).unwrap();
    assert!(camera.is_gige());
    assert_eq!(camera.model_name().unwrap(), "Fake");
    let (sensor_width, sensor_height) = camera.sensor_size().unwrap();
    assert!(sensor_width >= 1920 && sensor_height >= 1080);
    camera.set_region(0, 0, 1920, 1080).unwrap();
    camera.set_pixel_format(RGB_8).unwrap();
    assert_eq!(camera.pixel_format().unwrap(), RGB_8);
    camera.set_frame_rate(30.0).unwrap();
    camera.set_exposure_us(5000.0).unwrap();
    assert!((camera.exposure_us().unwrap() - 5000.0).abs() < 1.0);
    camera.set_gige_packet_size(8000).unwrap();
    camera.set_continuous().unwrap();
    let mut stream = camera.create_stream(4).unwrap();
    assert_eq!(stream.payload_bytes(), 1920 * 1080 * 3);
    camera.start_acquisition().unwrap();
    let mut complete = 0;
    for _ in 0..20 {
        let Some(buffer) = stream.pop(Duration::from_secs(2)) else {
            continue;
        };
        if buffer.status() != BufferStatus::Success {
            continue;
        }
        assert_eq!((buffer.width(), buffer.height()), (1920, 1080));
        assert_eq!(buffer.pixel_format(), RGB_8);
        let data = buffer.data();
        assert_eq!(data.len(), 1920 * 1080 * 3);
        assert_eq!(data[0], (buffer.frame_id() % 200) as u8);
        assert_eq!(data[1000], (1000 % 251) as u8);
        assert!(buffer.timestamp_ns() > 0);
        complete += 1;
        if complete == 5 {
            break;
        }
    }
    assert_eq!(complete, 5);
    let stats = stream.statistics();
    assert!(stats.completed_buffers >= 5, "{stats:?}");
    camera.stop_acquisition().unwrap();
    drop(stream);
    // Mono8 after a stop: a new stream of the new payload.
    camera.set_pixel_format(MONO_8).unwrap();
    let mut stream = camera.create_stream(2).unwrap();
    assert_eq!(stream.payload_bytes(), 1920 * 1080);
    camera.start_acquisition().unwrap();
    let mut found = None;
    for _ in 0..10 {
        if let Some(buffer) = stream.pop(Duration::from_secs(2))
            && buffer.status() == BufferStatus::Success
        {
            found = Some((buffer.pixel_format(), buffer.data().len()));
            break;
        }
    }
    assert_eq!(found, Some((MONO_8, 1920 * 1080)));
}

#[test]
fn no_camera_at_an_address_is_an_error_not_a_hang() {
    // Aravis is required (`.ci/run` installs it): its error names the package to install.
    let aravis = Aravis::load().unwrap_or_else(|error| panic!("{error}"));
    let error = Camera::open(&aravis, Some("Aravis-NOSUCHCAMERA")).unwrap_err();
    assert!(
        matches!(
            error,
            AravisError::Call { .. } | AravisError::NoObject { .. }
        ),
        "{error}"
    );
}

#[test]
fn a_missing_library_is_named_with_the_package_to_install() {
    let error = Aravis::load_named("libaravis-0.8-not-installed.so.0").unwrap_err();
    let message = error.to_string();
    assert!(
        matches!(error, AravisError::NotInstalled { .. }),
        "{message}"
    );
    assert!(
        message.contains("libaravis-0.8-not-installed.so.0")
            && message.contains("apt-get install libaravis-0.8-0"),
        "{message}"
    );
}
