//! Property test of the arm settings reader: a complete settings file (with
//! its `[node]` table) with values replaced by anything (NaN, negative, huge, wrongly typed),
//! lines dropped or doubled and bytes changed. The file is refused with an error naming it, or
//! the node it configures is refused, or that node drives its arm to a target with set-points
//! that are finite and inside the Table 1 joint limits; never a panic.

use harvest_arm::node::{ArmNode, ArmNodeConfig, ArmNodeInput, EncoderSample, ServoOrder};
use harvest_arm_process::ArmDevice;
use harvest_arm_process::process::ArmProcessConfig;
use harvest_ipc::payloads::{ArmTarget, VacuumState};
use harvest_robot_model::params::{ArmId, ArmParams};
use harvest_test_support::toml_mutation::{mutate_toml, scratch_file, toml_edit};
use proptest::prelude::*;

/// Cases: each reads one file and runs up to 300 control periods.
const CASES: u32 = 128;

/// The complete settings file of the simulated arm, every key written out.
fn complete_settings() -> String {
    #[derive(serde::Serialize)]
    struct Settings {
        control_period_us: u64,
        valve_request_resend_ms: u64,
        node: ArmNodeConfig,
    }
    toml::to_string(&Settings {
        control_period_us: 5000,
        valve_request_resend_ms: 500,
        node: ArmDevice::Sim.node_config(),
    })
    .expect("settings")
}

/// Runs the node configured by `config` for 300 ticks toward a reachable apple, with servos
/// that follow their set-points; checks every set-point.
fn drive(config: ArmNodeConfig) -> Result<(), TestCaseError> {
    let node = ArmNode::new(ArmId::Arm1, config);
    let mut node = match node {
        Ok(node) => node,
        Err(error) => {
            prop_assert!(!error.to_string().is_empty());
            return Ok(());
        }
    };
    let params = ArmParams::for_arm(ArmId::Arm1);
    let lo = params.position_limits.min.to_array();
    let hi = params.position_limits.max.to_array();
    let mut q = params.home.to_array();
    let mut v = [0.0; 4];
    let target = ArmTarget {
        arm_id: 1,
        apple_id: 5,
        position_in_robot_m: [1.487, -0.05, 0.50],
        radius_m: 0.037,
        source_capture_ns: 10_000_000_000,
        ..ArmTarget::default()
    };
    let vacuum = VacuumState::default();
    for tick in 0..300u64 {
        let now_ns = 10_000_000_000 + tick * 5_000_000;
        let input = ArmNodeInput {
            now_ns,
            feedback: Some(EncoderSample {
                capture_ns: now_ns,
                position: q,
                velocity: v,
            }),
            target: Some(&target),
            vacuum: Some(&vacuum),
            ..ArmNodeInput::default()
        };
        match node.step(&input).servo {
            ServoOrder::Hold => v = [0.0; 4],
            ServoOrder::Track { position, velocity } => {
                for j in 0..4 {
                    prop_assert!(
                        position[j].is_finite() && (lo[j]..=hi[j]).contains(&position[j]),
                        "tick {tick}: joint {j} set-point {}",
                        position[j]
                    );
                    prop_assert!(
                        velocity[j].is_finite(),
                        "tick {tick}: joint {j} rate {}",
                        velocity[j]
                    );
                }
                q = position;
                v = velocity;
            }
        }
    }
    Ok(())
}

/// The bench works: the complete file reads back and its node moves the arm.
#[test]
fn the_complete_settings_file_reads_back() {
    let path = scratch_file("harvest-settings-prop", &complete_settings());
    let config = ArmProcessConfig::from_path(&path).expect("settings");
    let _ = std::fs::remove_file(&path);
    assert_eq!(config.node, Some(ArmDevice::Sim.node_config()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn mutated_arm_settings_are_refused_by_name_or_drive_safely(
        edits in prop::collection::vec(toml_edit(), 1..5),
    ) {
        let path = scratch_file("harvest-settings-prop", &mutate_toml(&complete_settings(), &edits));
        let read = ArmProcessConfig::from_path(&path);
        let _ = std::fs::remove_file(&path);
        match read {
            Ok(config) => drive(config.node.unwrap_or(ArmDevice::Sim.node_config()))?,
            Err(error) => {
                let message = error.to_string();
                prop_assert!(
                    message.contains("harvest-settings-prop") || message.contains("control_period_us")
                        || message.contains("valve_request_resend_ms"),
                    "{message}"
                );
            }
        }
    }
}
