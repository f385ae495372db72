//! Property test of the vacuum settings reader: a complete settings file
//! (with its `[node]` and `[arm_node]` tables) with values replaced by anything (NaN, negative,
//! huge, wrongly typed), lines dropped or doubled and bytes changed. The file is refused with
//! an error naming it, or the node it configures is refused, or that node runs a detection set
//! and answers valve requests without panicking.

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_ipc::payloads::{AppleDetection, AppleDetections, ArmState, ValveRequest};
use harvest_robot_model::ArmId;
use harvest_robot_model::params::ArmId as ArmNumber;
use harvest_test_support::toml_mutation::{mutate_toml, scratch_file, toml_edit};
use harvest_vacuum::node::{BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeInput};
use harvest_vacuum_process::process::{VacuumDevice, VacuumProcessConfig};
use proptest::prelude::*;

/// Cases: each reads one file and runs 100 control periods.
const CASES: u32 = 128;

/// The complete settings file of the simulated vacuum, every key written out.
fn complete_settings() -> String {
    #[derive(serde::Serialize)]
    struct Settings {
        control_period_us: u64,
        complete_after_ms: u64,
        board_timeout_ms: u64,
        node: VacuumNodeConfig,
        arm_node: ArmNodeConfig,
    }
    toml::to_string(&Settings {
        control_period_us: 5000,
        complete_after_ms: 2000,
        board_timeout_ms: 100,
        node: VacuumNodeConfig {
            pressure: VacuumDevice::Sim.pressure_config(),
            ..VacuumNodeConfig::default()
        },
        arm_node: VacuumDevice::Sim.arm_node_config(),
    })
    .expect("settings")
}

/// Runs the node configured by `config` for 100 ticks with a detection set and standing
/// requests.
fn run(config: &VacuumProcessConfig) -> Result<(), TestCaseError> {
    let node_config = config.node.unwrap_or(VacuumNodeConfig {
        pressure: VacuumDevice::Sim.pressure_config(),
        ..VacuumNodeConfig::default()
    });
    let arm_node = config
        .arm_node
        .unwrap_or_else(|| VacuumDevice::Sim.arm_node_config());
    let node = VacuumNode::new(
        node_config,
        Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
            let arm = [ArmNumber::Arm1, ArmNumber::Arm2][arm.index()];
            pick_reachable(arm, *centre, radius_m, &arm_node)
        }),
    );
    let mut node = match node {
        Ok(node) => node,
        Err(error) => {
            prop_assert!(!error.to_string().is_empty());
            return Ok(());
        }
    };
    let mut detections = AppleDetections::default();
    for (k, position) in [[1.487, -0.05, 0.50], [1.45, 0.20, 0.45]]
        .into_iter()
        .enumerate()
    {
        let _ = detections.apples.push(AppleDetection {
            apple_id: k as u32 + 1,
            position_in_robot_m: position,
            radius_m: 0.037,
            ..AppleDetection::default()
        });
    }
    let states = [1u8, 2].map(|arm_id| ArmState {
        arm_id,
        ..ArmState::default()
    });
    let requests = [1u8, 2].map(|arm_id| ValveRequest {
        arm_id,
        ..ValveRequest::default()
    });
    for tick in 0..100u64 {
        let now_ns = 10_000_000_000 + tick * 5_000_000;
        let input = VacuumNodeInput {
            now_ns,
            arm_states: [Some(&states[0]), Some(&states[1])],
            valve_requests: [Some(&requests[0]), Some(&requests[1])],
            readings: Some(BoardReadings {
                stamp_ns: now_ns,
                valve_open: [false, true, false, true],
                pressure_mmh2o: [0.0, 0.0, 2400.0],
                ..BoardReadings::default()
            }),
            detections: (tick % 20 == 0).then_some(&detections),
            emergency_stop: false,
        };
        let _ = node.step(&input);
    }
    Ok(())
}

/// The bench works: the complete file reads back.
#[test]
fn the_complete_settings_file_reads_back() {
    let path = scratch_file("harvest-settings-prop", &complete_settings());
    let config = VacuumProcessConfig::from_path(&path).expect("settings");
    let _ = std::fs::remove_file(&path);
    assert!(config.node.is_some() && config.arm_node.is_some());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn mutated_vacuum_settings_are_refused_by_name_or_run(
        edits in prop::collection::vec(toml_edit(), 1..5),
    ) {
        let path = scratch_file("harvest-settings-prop", &mutate_toml(&complete_settings(), &edits));
        let read = VacuumProcessConfig::from_path(&path);
        let _ = std::fs::remove_file(&path);
        match read {
            Ok(config) => run(&config)?,
            Err(error) => prop_assert!(!error.to_string().is_empty()),
        }
    }
}
