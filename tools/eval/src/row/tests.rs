//! A one-stop row with perception in the loop: reproducible from its seed, counts consistent
//! with the ground truth, the single-arm mode uses arm 1 only.

use harvest_arm::node::ArmNodeConfig;
use harvest_sim::row::RowScenario;
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::PressureConfig;

use super::args::DetectionsArg;
use super::perception_loop::FramePolicy;
use super::report::{RowRunReport, load_row};
use super::runner::{RowOutcome, RowRunConfig, run_row};
use crate::harvest::TimingArg;
use crate::harvest::calibration::pressure_for;
use crate::harvest::timing::{SCENARIO_ATTACH_TIMEOUT_NS, apply_timing};

/// One section of the default fruiting wall: one stop.
const ONE_STOP: &str = r#"name = "one_stop"
[[section]]
canopy = "default"
center_m = 0.0
"#;

fn config(arms: u8, seed: u64) -> RowRunConfig {
    let mut row = RowScenario::from_toml_str("one_stop.toml", ONE_STOP).expect("row");
    let mut arm_node = ArmNodeConfig::default();
    let mut pressure = PressureConfig::default();
    apply_timing(
        &mut row.scenarios[0],
        &mut arm_node,
        &mut pressure,
        TimingArg::Scenario,
    );
    assert_eq!(pressure.attach_timeout_ns, SCENARIO_ATTACH_TIMEOUT_NS);
    let pressure = pressure_for(&row.scenarios[0].vacuum, pressure).expect("thresholds");
    RowRunConfig {
        name: "one_stop".to_owned(),
        row,
        seed,
        arms,
        policy: PolicyKind::V2024,
        arm_node,
        pressure,
        detections: DetectionsArg::Perception,
        frames: FramePolicy {
            harvest_interval_ns: 1_500_000_000,
            waiting_interval_ns: 500_000_000,
            latency_ns: 100_000_000,
        },
        quiet_ns: 4_000_000_000,
        max_row_s: 600.0,
    }
}

fn check_truth(outcome: &RowOutcome, report: &RowRunReport) {
    assert!(outcome.row_report.is_some(), "the row completed");
    assert_eq!(outcome.stops.len(), 1);
    assert!(
        report.counts.harvested as usize <= report.counts.reachable,
        "{report:?}"
    );
    assert!(
        report.counts.reachable <= report.counts.apples_on_row,
        "{report:?}"
    );
    assert_eq!(
        report.counts.reachable + report.counts.out_of_reach,
        report.counts.apples_on_row
    );
    // Every apple of the row is accounted for: harvested, or still somewhere with a state.
    let on_module = outcome
        .world
        .apples()
        .iter()
        .filter(|a| a.state == harvest_sim::AppleState::Harvested)
        .count();
    assert_eq!(on_module, report.counts.harvested as usize);
    assert_eq!(outcome.world.apples().len(), report.counts.apples_on_row);
    // Every failed, ended attempt has a Table 3 cause; harvested ones have none.
    let failed = outcome
        .episode
        .recorder
        .attempts
        .iter()
        .filter(|a| !a.harvested && a.ended_s.is_some())
        .count() as u32;
    let harvested_attempts = outcome
        .episode
        .recorder
        .attempts
        .iter()
        .filter(|a| a.harvested)
        .count() as u32;
    assert_eq!(harvested_attempts, report.counts.harvested);
    assert_eq!(failed, report.failure_detail.values().sum::<u32>());
    assert!(report.counts.failures.values().sum::<u32>() >= failed);
    // Every failed attempt has one origin, and the list holds each once.
    assert_eq!(failed, report.counts.origins.values().sum::<u32>());
    assert_eq!(failed as usize, report.failed.len());
    assert!(
        report.counts.attempts > 0,
        "perception found apples to pick: {report:?}"
    );
    assert!(report.frames > 0);
    assert_eq!(
        report.counts.safety_violations, 0,
        "{:?}",
        outcome.episode.violations
    );
}

#[test]
fn a_row_is_reproducible_from_its_seed_and_consistent_with_the_ground_truth() {
    let first = run_row(&config(2, 3)).expect("run");
    let second = run_row(&config(2, 3)).expect("run again");
    let (a, b) = (RowRunReport::of(&first), RowRunReport::of(&second));
    assert_eq!(a, b, "same seed, same figures");
    check_truth(&first, &a);
}

#[test]
fn the_single_arm_mode_uses_arm_1_only() {
    let outcome = run_row(&config(1, 3)).expect("run");
    let report = RowRunReport::of(&outcome);
    check_truth(&outcome, &report);
    assert!(outcome.episode.recorder.attempts.iter().all(|a| a.arm == 1));
}

#[test]
fn the_presets_load_and_unknown_rows_are_named() {
    for name in ["two_stops", "three_sections"] {
        load_row(name).expect("preset");
    }
    let error = load_row("no/such/row.toml").expect_err("missing file");
    assert!(error.to_string().contains("no/such/row.toml"), "{error}");
}
