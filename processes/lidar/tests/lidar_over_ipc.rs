//! The LiDAR path over real shared memory: the simulator's LiDAR device publishing frames on
//! `hw/lidar/points`, the driver integrating them into one cloud, and the cloud fused into the
//! simulated colour camera lands on the objects the camera renders there.

use harvest_hw::lidar::sim::SimLidar;
use harvest_hw::lidar::{Lidar, LidarSpec};
use harvest_ipc::payloads::PointCloud;
use harvest_ipc::{Context, ScratchDomain};
use harvest_lidar::fusion::{Fusion, FusionConfig, PointFate};
use harvest_sim::lidar_device::{LidarDeviceConfig, LidarDevicePort};
use harvest_sim::render_rgbd::{apple_from_label, label};
use harvest_sim::{RgbdRenderer, Scenario, World};
use std::time::Duration;

fn noiseless() -> LidarDeviceConfig {
    LidarDeviceConfig {
        spec: LidarSpec {
            range_sigma_m: 0.0,
            angular_sigma_deg: 0.0,
            ..LidarSpec::mid70()
        },
        ..LidarDeviceConfig::default()
    }
}

#[test]
fn integrated_cloud_over_ipc_fuses_onto_the_rendered_apples() {
    let domain = ScratchDomain::new("lidar_ipc");
    let device_context = Context::new(&domain, "sim").expect("device node");
    let driver_context = Context::new(&domain, "lidar").expect("driver node");
    let mut driver = SimLidar::connect(&driver_context, Duration::from_secs(1)).expect("driver");
    let config = noiseless();
    let mut device = LidarDevicePort::open(&device_context, config).expect("device");
    let world = World::generate(&Scenario::preset("ideal").expect("ideal"), 4).expect("world");
    let mut cloud: Box<PointCloud> = harvest_ipc::payload::boxed_zeroed();

    // Nothing sent yet: the capture times out without writing.
    assert!(
        !driver
            .capture_into(&mut cloud, Duration::from_millis(20))
            .expect("capture")
    );
    let mut frames = 0;
    let delivered = loop {
        device.tick(&world).expect("device frame");
        frames += 1;
        if driver
            .capture_into(&mut cloud, Duration::from_millis(500))
            .expect("capture")
        {
            break true;
        }
        if frames > 20 {
            break false;
        }
    };
    assert!(delivered, "no cloud after {frames} device frames");
    assert_eq!(frames, 10, "a 1 s window is ten 100 ms frames");
    assert_eq!(cloud.meta.integration_ns, 1_000_000_000);
    assert_eq!(cloud.meta.flags, 0);
    let points = cloud.valid_points();
    assert!(points.len() > 50_000, "{} points", points.len());

    // Fuse into the ToF colour camera with the true extrinsic: every visible point on an apple
    // lands on that apple's pixels in the rendered label image.
    let mut renderer = RgbdRenderer::new(&world.scenario().camera).expect("renderer");
    let color = *renderer.color_intrinsics();
    let mut labels = vec![0u32; (color.width_px * color.height_px) as usize];
    renderer.render_labels(&world, &mut labels).expect("labels");
    let mut fusion =
        Fusion::new(FusionConfig::new(color, config.camera_from_lidar)).expect("fusion");
    let stats = fusion.fuse(points).expect("fuse");
    assert!(stats.visible > 30_000, "{stats:?}");
    let robot_from_color = renderer.robot_from_color();
    let (mut on_apples, mut matching) = (0usize, 0usize);
    for ((fate, &pixel), point) in fusion
        .fates()
        .iter()
        .zip(fusion.point_pixels())
        .zip(fusion.points_in_camera_m())
    {
        if *fate != PointFate::Visible {
            continue;
        }
        let in_robot = robot_from_color.apply(point.map(f64::from));
        let apple = world.apples().iter().find(|apple| {
            let d = (0..3)
                .map(|k| (in_robot[k] - apple.center_in_robot_m[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            (d - apple.radius_m).abs() < 1e-3
        });
        if let Some(apple) = apple {
            on_apples += 1;
            let seen = labels[pixel as usize];
            matching +=
                usize::from(seen >= label::APPLE_BASE && apple_from_label(seen) == Some(apple.id));
        }
    }
    assert!(on_apples > 500, "{on_apples} points on apples");
    // Points at an apple's rim may round onto the neighbouring pixel.
    assert!(
        matching as f64 > 0.97 * on_apples as f64,
        "{matching} of {on_apples} apple points on their apple's pixels"
    );
}
