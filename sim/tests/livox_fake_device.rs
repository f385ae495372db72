//! The Livox driver (`harvest_hw::lidar::livox`) against the fake Mid-70 over UDP on loopback:
//! the LiDAR conformance suite (the same one the simulated driver passes in
//! `tests/sim_devices.rs`), then each fault the fake can inject: dropped packets counted
//! exactly, corrupted datagrams counted by reason and dropped, silence reported and the device
//! reconnected when it returns, a reboot survived, discovery by broadcast code, dual returns.

use harvest_hw::conformance::TestWatchdog;
use harvest_hw::lidar::conformance::{LidarConformanceConfig, conformance_suite};
use harvest_hw::lidar::livox::command::BroadcastCode;
use harvest_hw::lidar::livox::point_packet::{DataType, TimestampType};
use harvest_hw::lidar::livox::{DeviceTarget, LivoxConfig, LivoxError, LivoxLidar};
use harvest_hw::lidar::{Lidar, LidarCondition};
use harvest_hw::{DeviceError, ErrorKind};
use harvest_ipc::payload::boxed_zeroed;
use harvest_ipc::payloads::PointCloud;
use harvest_sim::fake_mid70::{FakeFault, FakeMid70, FakeMid70Config};
use std::net::{Ipv4Addr, SocketAddr};
use std::time::{Duration, Instant};

const WATCHDOG: Duration = Duration::from_secs(240);
const CODE: &str = "3GGDJ6K00100101";

fn code() -> BroadcastCode {
    BroadcastCode::parse(CODE).expect("code")
}

fn fake(config: FakeMid70Config) -> FakeMid70 {
    FakeMid70::start(config).expect("fake mid-70")
}

/// A driver for the fake at `device`, ephemeral host ports, window `integration`.
fn driver(device: SocketAddr, integration: Duration) -> LivoxLidar {
    let SocketAddr::V4(device) = device else {
        panic!("IPv4 expected")
    };
    LivoxLidar::open(LivoxConfig {
        host_ip: Some(Ipv4Addr::LOCALHOST),
        device_cmd_port: device.port(),
        host_cmd_port: 0,
        host_data_port: 0,
        integration,
        ..LivoxConfig::new(DeviceTarget::Address(*device.ip()))
    })
    .expect("open driver")
}

/// Captures until a window arrives, allowing the driver's transient errors; panics after `limit`.
fn next_window(lidar: &mut LivoxLidar, cloud: &mut PointCloud, limit: Duration) -> Vec<String> {
    let deadline = Instant::now() + limit;
    let mut errors = Vec::new();
    while Instant::now() < deadline {
        match lidar.capture_into(cloud, Duration::from_millis(250)) {
            Ok(true) => return errors,
            Ok(false) => {}
            Err(error) => errors.push(error.to_string()),
        }
    }
    panic!(
        "no window within {limit:?}; errors {errors:?}; {:?}",
        lidar.stats()
    );
}

#[test]
fn livox_driver_passes_the_lidar_conformance_suite_against_the_fake() {
    let _watchdog = TestWatchdog::arm("livox conformance", WATCHDOG);
    let device = fake(FakeMid70Config::loopback(code()));
    // The silent device: an address where nothing answers.
    let nobody = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
    let integration = Duration::from_millis(200);
    let config = LidarConformanceConfig::mid70(integration);
    let report = conformance_suite(
        &config,
        || driver(device.cmd_addr(), integration),
        || driver(nobody.local_addr().expect("addr"), integration),
    )
    .expect("conformance suite");
    assert_eq!(report.checks_passed.len(), 4, "{report:?}");
}

#[test]
fn dropped_and_corrupted_packets_are_counted_and_the_stream_goes_on() {
    let _watchdog = TestWatchdog::arm("livox faults", WATCHDOG);
    let device = fake(FakeMid70Config::loopback(code()));
    let mut lidar = driver(device.cmd_addr(), Duration::from_millis(100));
    let mut cloud: Box<PointCloud> = boxed_zeroed();
    for _ in 0..3 {
        next_window(&mut lidar, &mut cloud, Duration::from_secs(10));
    }
    assert_eq!(lidar.stats().lost_packets, 0, "{:?}", lidar.stats());
    device.inject(FakeFault::Drop { packets: 17 });
    device.inject(FakeFault::Corrupt { packets: 10 });
    // Past the next heartbeat (once a second), whose acknowledgement comes corrupted first.
    for _ in 0..15 {
        next_window(&mut lidar, &mut cloud, Duration::from_secs(10));
    }
    let stats = lidar.stats();
    let fake = device.stats();
    assert_eq!(fake.packets_dropped, 17);
    assert_eq!(fake.packets_corrupted, 10);
    // Each corrupted packet replaced a good one: 27 missing from the stream.
    assert_eq!(stats.lost_packets, 27, "{stats:?}");
    let bad = stats.bad_packets;
    assert_eq!(bad.total(), 10, "{bad:?}");
    assert_eq!(
        [
            bad.truncated,
            bad.bad_length,
            bad.bad_version,
            bad.unknown_data_type,
            bad.unknown_timestamp_type
        ],
        [2, 2, 2, 2, 2]
    );
    assert!(stats.session.bad_frames >= 1, "{stats:?}");
    assert_eq!(lidar.health().lost_packets, 27);
}

#[test]
fn a_silent_device_is_reported_and_reconnected_and_a_reboot_is_survived() {
    let _watchdog = TestWatchdog::arm("livox silence", WATCHDOG);
    let device = fake(FakeMid70Config::loopback(code()));
    let mut lidar = driver(device.cmd_addr(), Duration::from_millis(100));
    let mut cloud: Box<PointCloud> = boxed_zeroed();
    next_window(&mut lidar, &mut cloud, Duration::from_secs(10));
    assert!(lidar.health().connected);

    device.inject(FakeFault::Silent(Duration::from_secs(4)));
    let silent_since = Instant::now();
    let error = loop {
        match lidar.capture_into(&mut cloud, Duration::from_millis(250)) {
            Err(error) => break error,
            Ok(_) => assert!(silent_since.elapsed() < Duration::from_secs(10)),
        }
    };
    assert!(matches!(error, LivoxError::Silent { .. }), "{error}");
    assert_eq!(error.kind(), ErrorKind::Disconnected);
    assert!(!lidar.health().connected);
    // Reconnected once the device speaks again, with no loss counted for the silence.
    let errors = next_window(&mut lidar, &mut cloud, Duration::from_secs(15));
    assert!(errors.is_empty(), "{errors:?}");
    let stats = lidar.stats();
    assert_eq!(stats.session.reconnects, 1, "{stats:?}");
    assert_eq!(stats.lost_packets, 0, "{stats:?}");

    device.inject(FakeFault::Reboot(Duration::from_millis(2500)));
    let errors = next_window(&mut lidar, &mut cloud, Duration::from_secs(20));
    assert!(!errors.is_empty(), "the reboot went unnoticed");
    next_window(&mut lidar, &mut cloud, Duration::from_secs(5));
    assert_eq!(device.stats().reboots, 1);
    assert!(device.stats().handshakes >= 2);
    assert_eq!(lidar.stats().session.reconnects, 2);
    assert!(lidar.health().connected);
}

#[test]
fn status_word_goes_into_health() {
    let _watchdog = TestWatchdog::arm("livox status", WATCHDOG);
    let device = fake(FakeMid70Config::loopback(code()));
    let mut lidar = driver(device.cmd_addr(), Duration::from_millis(100));
    let mut cloud: Box<PointCloud> = boxed_zeroed();
    next_window(&mut lidar, &mut cloud, Duration::from_secs(10));
    assert_eq!(lidar.health().condition, LidarCondition::Normal);
    // Motor warning, system warning.
    device.inject(FakeFault::Status((1 << 4) | (1 << 30)));
    next_window(&mut lidar, &mut cloud, Duration::from_secs(5));
    next_window(&mut lidar, &mut cloud, Duration::from_secs(5));
    assert_eq!(
        lidar.health().condition,
        LidarCondition::Warning("motor_warning")
    );
}

#[test]
fn discovery_by_broadcast_code_and_dual_returns_under_ptp() {
    let _watchdog = TestWatchdog::arm("livox discovery", WATCHDOG);
    // The host's discovery port: a free one (55000 may be taken on a shared machine).
    let probe = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
    let discovery_port = probe.local_addr().expect("addr").port();
    drop(probe);
    let device = fake(FakeMid70Config {
        broadcast_to: Some(SocketAddr::from((Ipv4Addr::LOCALHOST, discovery_port))),
        data_type: DataType::DualExtendedCartesian,
        timestamp_type: TimestampType::Ptp,
        ..FakeMid70Config::loopback(code())
    });
    let integration = Duration::from_millis(100);
    let mut lidar = LivoxLidar::open(LivoxConfig {
        host_ip: Some(Ipv4Addr::LOCALHOST),
        discovery_port,
        host_cmd_port: 0,
        host_data_port: 0,
        integration,
        ..LivoxConfig::new(DeviceTarget::Broadcast(code()))
    })
    .expect("open driver");
    let mut cloud: Box<PointCloud> = boxed_zeroed();
    next_window(&mut lidar, &mut cloud, Duration::from_secs(10));
    next_window(&mut lidar, &mut cloud, Duration::from_secs(5));
    assert_eq!(lidar.session().device(), Some(device.cmd_addr()));
    // Two returns per firing: the window holds twice the returns of its firings.
    assert_eq!(cloud.meta.integration_ns, 100_000_000);
    let stats = lidar.stats();
    assert_eq!(stats.lost_packets, 0, "{stats:?}");
    assert!(cloud.meta.point_count > 2 * 5_000, "{:?}", cloud.meta);
}
