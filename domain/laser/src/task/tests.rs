//! The laser's node under the robot's tick (`harvest_node::Runner`) on the in-process bus, with
//! the rendered ALACS unit behind a fake that counts the exchanges, knows the laser's state and
//! fails an exchange on demand.

use super::*;
use harvest_hw::alacs::{
    ALACS_FROM_TOF_CAMERA, AlacsError, AlacsExtrinsics, AlacsFrameInfo, AlacsPart,
    alacs_camera_intrinsics,
};
use harvest_hw::{DeviceError, ErrorKind};
use harvest_ipc::camera_model::CameraIntrinsics;
use harvest_ipc::catalogue::EMERGENCY_STOP;
use harvest_ipc::payloads::{EmergencyStop, ProcessRunState};
use harvest_node::in_process::{Bus, Cursors, InProcess};
use harvest_node::{Runner, RunnerConfig};
use harvest_robot_model::ModeSource;
use harvest_sim::alacs::{AlacsScene, AppleSphere, RenderedAlacs, RenderedAlacsConfig};

/// The apple the unit sees, ALACS camera frame, m.
const APPLE_IN_ALACS_M: [f64; 3] = [0.03, 0.02, 0.9];

/// Half the ALACS camera's resolution, same field of view, to keep the tests quick.
fn camera() -> CameraIntrinsics {
    let mut intrinsics = alacs_camera_intrinsics();
    intrinsics.width_px /= 2;
    intrinsics.height_px /= 2;
    intrinsics.fx_px *= 0.5;
    intrinsics.fy_px *= 0.5;
    intrinsics.cx_px = (intrinsics.width_px as f64 - 1.0) / 2.0;
    intrinsics.cy_px = (intrinsics.height_px as f64 - 1.0) / 2.0;
    intrinsics
}

/// The rendered unit, counting exchanges; the `fail_at`-th exchange fails (disconnected).
struct FakeUnit {
    rendered: RenderedAlacs,
    exchanges: usize,
    fail_at: Option<usize>,
    laser_on: bool,
}

impl FakeUnit {
    fn new() -> Self {
        let scene = AlacsScene {
            apples: vec![AppleSphere {
                centre_in_camera_m: APPLE_IN_ALACS_M,
                radius_m: 0.04,
                rgb: [160, 35, 30],
            }],
            background_depth_m: Some(1.6),
            ..AlacsScene::default()
        };
        Self {
            rendered: RenderedAlacs::new(camera(), RenderedAlacsConfig::default(), scene)
                .expect("unit"),
            exchanges: 0,
            fail_at: None,
            laser_on: false,
        }
    }

    fn exchange(&mut self) -> Result<(), AlacsError> {
        self.exchanges += 1;
        if self.fail_at == Some(self.exchanges) {
            return Err(AlacsError::Disconnected {
                part: AlacsPart::Slide,
                detail: "cable pulled".to_owned(),
            });
        }
        Ok(())
    }
}

impl AlacsUnit for FakeUnit {
    type Error = AlacsError;

    fn intrinsics(&self) -> CameraIntrinsics {
        self.rendered.intrinsics()
    }

    fn move_slide(&mut self, slide_position_m: f64) -> Result<f64, AlacsError> {
        self.exchange()?;
        self.rendered.move_slide(slide_position_m)
    }

    fn set_laser(&mut self, on: bool) -> Result<(), AlacsError> {
        self.exchange()?;
        self.rendered.set_laser(on)?;
        self.laser_on = on;
        Ok(())
    }

    fn capture_rgb(&mut self, rgb: &mut [u8]) -> Result<AlacsFrameInfo, AlacsError> {
        self.exchange()?;
        self.rendered.capture_rgb(rgb)
    }
}

/// The node on its devices, the bus and the simulated clock.
struct Harness {
    runner: Runner<LaserTask<FakeUnit>>,
    bus: Bus,
    cursors: Cursors,
    results_cursor: u64,
    now_ns: u64,
}

impl Harness {
    fn new(unit: FakeUnit) -> Self {
        let service = ScanService::new(
            AlacsExtrinsics::paper_table1(),
            camera(),
            ALACS_FROM_TOF_CAMERA,
        )
        .expect("service");
        let config = RunnerConfig {
            max_read_failures: u32::MAX,
            mode_source: ModeSource::WithoutOperator,
        };
        Self {
            runner: Runner::new(LaserTask::new(service), UnitDevices::new(unit), config),
            bus: Bus::default(),
            cursors: Cursors::default(),
            results_cursor: 0,
            now_ns: 1_000_000_000,
        }
    }

    fn unit(&self) -> &FakeUnit {
        self.runner.devices().unit()
    }

    fn task(&self) -> &LaserTask<FakeUnit> {
        self.runner.node()
    }

    /// One tick, 10 ms after the previous one.
    fn tick(&mut self) {
        self.now_ns += 10_000_000;
        let mut transport = InProcess {
            bus: &mut self.bus,
            cursors: &mut self.cursors,
            now_ns: self.now_ns,
        };
        self.runner.tick(&mut transport, self.now_ns).expect("tick");
    }

    /// Ticks as the runtime does after a wake-up: once, then while the node has more work;
    /// checks that no tick makes more than one exchange. Returns the ticks.
    fn run(&mut self) -> usize {
        let mut ticks = 0;
        loop {
            let before = self.unit().exchanges;
            self.tick();
            ticks += 1;
            assert!(
                self.unit().exchanges - before <= 1,
                "two exchanges in one tick"
            );
            if !self.runner.node().has_more_work() {
                return ticks;
            }
            assert!(ticks < 1000, "the node never ran out of work");
        }
    }

    /// A request for the apple at `rough_in_alacs_m` (the ALACS camera frame, sent in the ToF
    /// colour-camera frame as perception does).
    fn request(&mut self, request_seq: u32, rough_in_alacs_m: [f64; 3]) -> LaserScanRequest {
        let request = LaserScanRequest {
            request_seq,
            apple_id: 100 + request_seq,
            rough_position_in_camera_m: ALACS_FROM_TOF_CAMERA.inverse().apply(rough_in_alacs_m),
            rough_radius_m: 0.04,
            ..LaserScanRequest::default()
        };
        self.bus.publish(LASER_SCAN_REQUEST, request, self.now_ns);
        request
    }

    /// A request for the apple, 1.2 cm off in depth as a ToF estimate would be.
    fn request_apple(&mut self, request_seq: u32) -> LaserScanRequest {
        let [x, y, z] = APPLE_IN_ALACS_M;
        self.request(request_seq, [x + 0.003, y, z + 0.012])
    }

    fn emergency_stop(&mut self, engaged: bool) {
        let stop = EmergencyStop {
            engaged: u8::from(engaged),
            ..EmergencyStop::default()
        };
        self.bus.publish(EMERGENCY_STOP, stop, self.now_ns);
    }

    /// The results published since the last call.
    fn results(&mut self) -> Vec<LaserScanResult> {
        let mut results = Vec::new();
        self.bus
            .read_since(LASER_SCAN_RESULT, &mut self.results_cursor, |r| {
                results.push(r)
            });
        results
    }

    fn health(&mut self) -> NodeHealth {
        self.runner
            .node_mut()
            .health()
            .expect("the task says its health")
    }
}

#[test]
fn requests_are_answered_in_arrival_order_one_exchange_per_tick() {
    let mut harness = Harness::new(FakeUnit::new());
    harness.request_apple(1);
    // Behind the camera: out of reach, answered without an exchange.
    harness.request(2, [0.0, 0.0, -1.0]);
    harness.request_apple(3);
    let ticks = harness.run();
    let results = harness.results();
    let order: Vec<_> = results
        .iter()
        .map(|r| (r.request_seq, r.apple_id))
        .collect();
    assert_eq!(order, [(1, 101), (2, 102), (3, 103)]);
    let statuses: Vec<_> = results.iter().map(|r| r.status.get()).collect();
    assert_eq!(
        statuses,
        [
            Ok(LaserScanStatus::Ok),
            Ok(LaserScanStatus::OutOfReach),
            Ok(LaserScanStatus::Ok)
        ]
    );
    // Two scans of laser on + 5 x (move + capture) + laser off, one exchange per tick, and
    // the tick that reads the last answer.
    assert_eq!(harness.unit().exchanges, 24);
    assert_eq!(ticks, 25);
    assert!(!harness.unit().laser_on);
    // The scan took its 13 ticks on the tick clock; the refusal none.
    assert_eq!(results[0].scan_duration_ns, 12 * 10_000_000);
    assert_eq!(results[1].scan_duration_ns, 0);
    assert!(results[0].candidate_count >= 4, "{:?}", results[0]);
    // The last scan's result carries one of its capture stamps.
    let stamps_ns = &harness.task().service().last_motion().capture_stamps_ns;
    assert_eq!(stamps_ns.len(), 5);
    assert!(stamps_ns.contains(&results[2].header.capture_ns));
    let counts = *harness.task().counts();
    assert_eq!((counts.answered, counts.refined), (3, 2));
    assert_eq!(harness.health().state, ProcessRunState::Running);
}

#[test]
fn the_answer_is_the_blocking_services_answer() {
    let mut harness = Harness::new(FakeUnit::new());
    let request = harness.request_apple(7);
    harness.run();
    let mut stepped = harness.results()[0];
    let mut service = ScanService::new(
        AlacsExtrinsics::paper_table1(),
        camera(),
        ALACS_FROM_TOF_CAMERA,
    )
    .expect("service");
    let mut blocking = LaserScanResult::default();
    service
        .answer(&mut FakeUnit::new(), &request, &mut blocking, &mut || {})
        .expect("scan");
    // Byte for byte but the publisher's stamps and the duration (the tick clock here).
    stepped.header.msg_seq = blocking.header.msg_seq;
    stepped.header.publish_ns = blocking.header.publish_ns;
    stepped.scan_duration_ns = blocking.scan_duration_ns;
    assert_eq!(stepped, blocking);
}

#[test]
fn the_emergency_stop_switches_the_laser_off_and_ends_the_scan() {
    let mut harness = Harness::new(FakeUnit::new());
    harness.request_apple(1);
    // Laser on, move, capture: the scan is under way with the laser on.
    for _ in 0..4 {
        harness.tick();
    }
    assert!(harness.unit().laser_on);
    assert_eq!(harness.unit().exchanges, 4);
    assert_eq!(harness.health().detail, "scanning_apple");
    assert_eq!(harness.health().value, 101);

    harness.emergency_stop(true);
    harness.tick();
    assert!(!harness.unit().laser_on, "the stop switches the laser off");
    // Only the stop's own exchange (laser off): the scan made none.
    assert_eq!(harness.unit().exchanges, 5);
    let results = harness.results();
    assert_eq!(results.len(), 1);
    assert_eq!(results[0].request_seq, 1);
    assert_eq!(results[0].status, LaserScanStatus::DeviceError);
    assert_eq!(results[0].candidate_count, 0);
    assert!(!harness.task().has_more_work());

    // A request read while the stop is engaged is refused at once; the laser stays off.
    harness.request_apple(2);
    harness.tick();
    assert_eq!(harness.unit().exchanges, 5);
    let refused = harness.results();
    assert_eq!(refused.len(), 1);
    assert_eq!(
        (refused[0].request_seq, refused[0].status.get()),
        (2, Ok(LaserScanStatus::DeviceError))
    );

    // Released: nothing is resumed.
    harness.emergency_stop(false);
    harness.tick();
    assert_eq!(harness.unit().exchanges, 5);
    assert!(harness.results().is_empty());
    assert!(!harness.task().has_more_work());
    let counts = *harness.task().counts();
    assert_eq!((counts.stopped, counts.device_errors), (2, 0));
    // A stop is no device failure.
    assert_eq!(harness.health().state, ProcessRunState::Running);

    // The next request is scanned as usual.
    harness.request_apple(3);
    harness.run();
    let results = harness.results();
    assert_eq!(
        (results[0].request_seq, results[0].status.get()),
        (3, Ok(LaserScanStatus::Ok))
    );
    assert!(!harness.unit().laser_on);
}

#[test]
fn a_device_error_mid_scan_switches_the_laser_off_answers_device_error_and_degrades() {
    let mut unit = FakeUnit::new();
    // Laser on, move, capture, then the second move fails.
    unit.fail_at = Some(4);
    let mut harness = Harness::new(unit);
    harness.request_apple(1);
    harness.run();
    // The failed move, then the laser off.
    assert_eq!(harness.unit().exchanges, 5);
    assert!(!harness.unit().laser_on);
    let results = harness.results();
    assert_eq!(results.len(), 1);
    assert_eq!(results[0].status, LaserScanStatus::DeviceError);
    assert_eq!(results[0].position_in_camera_m, {
        let [x, y, z] = APPLE_IN_ALACS_M;
        ALACS_FROM_TOF_CAMERA
            .inverse()
            .apply([x + 0.003, y, z + 0.012])
    });
    let health = harness.health();
    assert_eq!(health.state, ProcessRunState::Degraded);
    assert_eq!(health.detail, "last_scan_ms");
    // The runtime saw the refused exchange, with its kind (the heartbeat's device error).
    assert_eq!(
        harness.runner.last_device_error(),
        Some(ErrorKind::Disconnected)
    );
    assert_eq!(harness.runner.device_failures(), (0, 1));
    assert_eq!(harness.task().counts().device_errors, 1);

    // The next scan succeeds: running again.
    harness.request_apple(2);
    harness.run();
    assert_eq!(harness.results()[0].status, LaserScanStatus::Ok);
    assert_eq!(harness.health().state, ProcessRunState::Running);
}

#[test]
fn the_end_of_the_run_switches_the_laser_off_and_answers_what_is_pending() {
    let mut harness = Harness::new(FakeUnit::new());
    harness.request_apple(1);
    harness.request_apple(2);
    for _ in 0..3 {
        harness.tick();
    }
    assert!(harness.unit().laser_on);
    let mut transport = InProcess {
        bus: &mut harness.bus,
        cursors: &mut harness.cursors,
        now_ns: harness.now_ns,
    };
    harness
        .runner
        .shutdown(&mut transport, harness.now_ns)
        .expect("shutdown");
    assert!(!harness.unit().laser_on);
    let results = harness.results();
    let answered: Vec<_> = results
        .iter()
        .map(|r| (r.request_seq, r.status.get()))
        .collect();
    assert_eq!(
        answered,
        [
            (1, Ok(LaserScanStatus::DeviceError)),
            (2, Ok(LaserScanStatus::DeviceError))
        ]
    );
}

#[test]
fn a_unit_failure_keeps_the_kind_and_the_message() {
    let error = AlacsError::Disconnected {
        part: AlacsPart::Camera,
        detail: "gone".to_owned(),
    };
    let failure = UnitFailure::new(&error);
    assert_eq!(failure.kind(), ErrorKind::Disconnected);
    assert!(failure.to_string().contains("gone"), "{failure}");
}
