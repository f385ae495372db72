//! The simulated orchard row as its own process (`harvest sim --row`), over real shared
//! memory: the tractor passes its conformance suite, the platform's travel of the row file is
//! enforced and the world follows the platform and the trailer, and the world's state (apples,
//! harvested set, trailer and platform positions) survives a `kill -9` of the sim process.

mod common;

use common::*;
use harvest_hw::conformance::TestWatchdog;
use harvest_hw::platform::sim::SimPlatform;
use harvest_hw::platform::{Platform, PlatformTravel};
use harvest_hw::tractor::Tractor;
use harvest_hw::tractor::conformance::{TractorConformanceConfig, conformance_suite};
use harvest_hw::tractor::sim::SimTractor;
use harvest_hw::{DeviceError, ErrorKind};
use harvest_ipc::catalogue::SIM_GROUND_TRUTH;
use harvest_ipc::payloads::GroundTruth;
use harvest_ipc::payloads::{TrueApple, TrueAppleState};
use harvest_ipc::{Context, Domain, Subscriber};
use harvest_sim::orchard::World;
use harvest_sim::row::RowScenario;
use harvest_sim::world_state::{OffTree, OffTreeApple, WorldState};
use std::path::Path;
use std::time::{Duration, Instant};

const WATCHDOG: Duration = Duration::from_secs(240);
const SEED: u64 = 3;

/// Two sections of the default preset, 2 m apart; a platform narrower than the default.
const ROW: &str = r#"name = "test_row"

[platform]
in_out_range_m = [0.0, 0.3]
up_down_range_m = [-0.1, 0.5]

[tractor]
speed_m_per_s = 0.5
start_m = 0.0

[[section]]
canopy = "default"
center_m = 0.0

[[section]]
canopy = "default"
center_m = 2.0
"#;

fn start_sim(domain: &str, row: &Path, state: &Path) -> Drained {
    Drained::spawn(
        domain,
        &[
            "sim",
            "--row",
            row.to_str().unwrap(),
            "--seed",
            &SEED.to_string(),
            "--state-file",
            state.to_str().unwrap(),
            "--camera-rate-hz",
            "1",
        ],
    )
}

/// Polls `probe` every 20 ms until it returns `Some` (the watchdog bounds the test).
fn wait_for<T>(what: &str, mut probe: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(value) = probe() {
            return value;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no {what} within 60 s"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The newest ground truth published after `after` (a stack-clock stamp).
fn truth_after(truth: &Subscriber<GroundTruth>, after_ns: u64) -> Vec<TrueApple> {
    wait_for("ground truth", || {
        let sample = truth.receive_latest().expect("receive")?;
        (sample.header.capture_ns > after_ns).then(|| sample.apples.iter().copied().collect())
    })
}

fn settle_platform(platform: &mut SimPlatform) -> [f64; 2] {
    wait_for("platform at rest", || {
        let position = platform.position().ok()?;
        (!position.in_motion).then_some([position.in_out_m, position.up_down_m])
    })
}

fn settle_tractor(tractor: &mut SimTractor) -> f64 {
    wait_for("tractor at rest", || {
        let position = tractor.position().ok()?;
        (!position.in_motion).then_some(position.position_m)
    })
}

fn now_ns() -> u64 {
    harvest_ipc::MonotonicClock::read_ns()
}

#[test]
fn simulated_tractor_passes_the_conformance_suite() {
    let _watchdog = TestWatchdog::arm("tractor", WATCHDOG);
    let dir = TempDir::new("tractor");
    let row = dir.write("row.toml", ROW);
    let domain_name = unique_domain("tractor");
    let sim = start_sim(&domain_name, &row, &dir.0.join("world.toml"));
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "tractor-test").expect("node");
    let report = conformance_suite(&TractorConformanceConfig::default(), || {
        SimTractor::connect(&context, Duration::from_secs(20)).expect("connect sim tractor")
    })
    .expect("conformance suite");
    assert_eq!(report.checks_passed.len(), 4, "{report:?}");
    let (status, _, stderr) = sim.interrupt_and_wait(Duration::from_secs(20));
    assert!(status.success(), "{stderr}");
}

#[test]
fn the_world_follows_the_platform_and_the_trailer_within_the_row_travel_and_survives_kill_9() {
    let _watchdog = TestWatchdog::arm("row restart", WATCHDOG);
    let dir = TempDir::new("row-restart");
    let row_path = dir.write("row.toml", ROW);
    let state_path = dir.0.join("world.toml");
    // A state as a previous run left it: three apples off the tree, trailer and platform moved.
    let row = RowScenario::from_toml_str("row.toml", ROW).expect("row");
    let world = World::generate_row(&row, SEED).expect("world");
    let mut saved = WorldState::of(&world, 0.4, [0.05, 0.1]);
    saved.off_tree = vec![
        OffTreeApple {
            apple_id: 2,
            state: OffTree::Harvested,
            center_in_robot_m: [1.0, 0.0, 0.2],
        },
        OffTreeApple {
            apple_id: 7,
            state: OffTree::Harvested,
            center_in_robot_m: [1.0, 0.1, 0.2],
        },
        OffTreeApple {
            apple_id: 40,
            state: OffTree::Dropped,
            center_in_robot_m: [1.2, 0.3, -0.85],
        },
    ];
    saved.store(&state_path).expect("write state");

    let domain_name = unique_domain("rowrestart");
    let domain = Domain::new(&domain_name).expect("domain");
    let context = Context::new(&domain, "row-test").expect("node");
    let truth = context.subscriber(SIM_GROUND_TRUTH).expect("ground truth");
    let sim = start_sim(&domain_name, &row_path, &state_path);

    // Restored from the file: positions and the off-tree apples.
    let mut platform =
        SimPlatform::connect(&context, PlatformTravel::default(), Duration::from_secs(20))
            .expect("platform");
    let mut tractor = SimTractor::connect(&context, Duration::from_secs(20)).expect("tractor");
    let at = settle_platform(&mut platform);
    assert!(
        (at[0] - 0.05).abs() < 1e-9 && (at[1] - 0.1).abs() < 1e-9,
        "{at:?}"
    );
    assert!((settle_tractor(&mut tractor) - 0.4).abs() < 1e-9);
    let before = truth_after(&truth, now_ns());
    assert_eq!(before.len(), world.apples().len());
    for (id, state) in [
        (2, TrueAppleState::Harvested),
        (7, TrueAppleState::Harvested),
        (40, TrueAppleState::Dropped),
        (3, TrueAppleState::OnTree),
    ] {
        assert_eq!(before[id].state, state, "apple {id}");
    }
    // The robot stands at row offset (0.05 + 0, 0.4, -0.1 + 0.1): apple 0 is seen shifted.
    let generated = world.apples()[0].center_in_robot_m;
    let seen = before[0].center_in_robot_m;
    for (axis, offset) in [0.05, 0.4, 0.0].into_iter().enumerate() {
        assert!(
            (seen[axis] - (generated[axis] - offset)).abs() < 1e-9,
            "{seen:?} {generated:?}"
        );
    }

    // The row's travel (0.3 m in-out) is narrower than the driver's: the device refuses.
    platform
        .move_to(0.4, 0.1)
        .expect("inside the driver's travel");
    let refused = wait_for("refusal", || platform.position().err());
    assert_eq!(refused.kind(), ErrorKind::InvalidRequest, "{refused}");
    // Moves inside the travel move the world the other way.
    platform.move_to(0.2, 0.3).expect("move");
    let at = settle_platform(&mut platform);
    assert_eq!(at, [0.2, 0.3]);
    tractor.advance(0.6).expect("advance");
    let trailer_m = settle_tractor(&mut tractor);
    assert!((trailer_m - 1.0).abs() < 1e-9, "{trailer_m}");
    let moved = truth_after(&truth, now_ns());
    let shift = [0.2 - 0.05, 1.0 - 0.4, 0.3 - 0.1];
    for (apple, earlier) in moved
        .iter()
        .zip(&before)
        .filter(|(apple, _)| apple.state == TrueAppleState::OnTree)
    {
        for (axis, shift_m) in shift.iter().enumerate() {
            let expected = earlier.center_in_robot_m[axis] - shift_m;
            assert!((apple.center_in_robot_m[axis] - expected).abs() < 1e-9);
        }
    }
    // The state file follows (written at a bounded rate), then the sim dies.
    wait_for("state file updated", || {
        let state = WorldState::load(&state_path).ok()??;
        ((state.trailer_m - 1.0).abs() < 1e-9 && state.platform_m == [0.2, 0.3]).then_some(())
    });
    drop((platform, tractor));
    let (status, _, _) = sim.kill9_and_wait();
    assert!(!status.success());
    // What `harvest up` does before restarting a crashed process.
    harvest_ipc::cleanup::remove_dead_nodes(&domain).expect("clean dead nodes");

    // Restarted: the same apples, the same harvested set, the same positions.
    let sim = start_sim(&domain_name, &row_path, &state_path);
    let mut platform =
        SimPlatform::connect(&context, PlatformTravel::default(), Duration::from_secs(20))
            .expect("platform");
    let mut tractor = SimTractor::connect(&context, Duration::from_secs(20)).expect("tractor");
    assert_eq!(settle_platform(&mut platform), [0.2, 0.3]);
    assert!((settle_tractor(&mut tractor) - 1.0).abs() < 1e-9);
    let after = truth_after(&truth, now_ns());
    assert_eq!(after.len(), moved.len());
    for (apple, earlier) in after.iter().zip(&moved) {
        assert_eq!(apple.apple_id, earlier.apple_id);
        assert_eq!(apple.state, earlier.state, "apple {}", apple.apple_id);
        for axis in 0..3 {
            assert!(
                (apple.center_in_robot_m[axis] - earlier.center_in_robot_m[axis]).abs() < 1e-9,
                "apple {} moved across the restart",
                apple.apple_id
            );
        }
    }
    let (status, _, stderr) = sim.interrupt_and_wait(Duration::from_secs(20));
    assert!(status.success(), "{stderr}");
    assert!(
        stderr.contains("world restored from its state file"),
        "{stderr}"
    );
}
