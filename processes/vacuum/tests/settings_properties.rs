//! Property test of the vacuum settings reader (issue 18, item 3): a complete settings file
//! (with its `[node]` and `[arm_node]` tables) with values replaced by anything (NaN, negative,
//! huge, wrongly typed), lines dropped or doubled and bytes changed. The file is refused with
//! an error naming it, or the node it configures is refused, or that node runs a detection set
//! and answers valve requests without panicking.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup is a failed test

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_ipc::payloads::{AppleDetection, AppleDetections, ArmState, ValveRequest};
use harvest_robot_model::ArmId;
use harvest_robot_model::params::ArmId as ArmNumber;
use harvest_vacuum::node::{BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeInput};
use harvest_vacuum_process::process::{VacuumDevice, VacuumProcessConfig};
use proptest::prelude::*;
use std::path::PathBuf;

/// Cases: each reads one file and runs 100 control periods.
const CASES: u32 = 128;

/// Values that break settings: NaN, infinities, signs, zeros, extremes, wrong types.
const WILD_VALUES: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "-0.0",
    "1e308",
    "5e-324",
    "18446744073709551615",
    "9223372036854775807",
    "-9223372036854775808",
    "\"\"",
    "\"x\"",
    "true",
    "[]",
    "[nan, inf, -1]",
    "{}",
    "0.000001",
    "100000",
];

/// One edit of a TOML text.
#[derive(Debug, Clone)]
enum TomlEdit {
    /// The value of the n-th `key = value` line replaced.
    Value(prop::sample::Index, &'static str),
    /// The n-th line removed.
    DropLine(prop::sample::Index),
    /// The n-th line written twice.
    DuplicateLine(prop::sample::Index),
    /// One byte replaced (syntax errors, cut strings, control characters).
    Byte(prop::sample::Index, u8),
}

fn toml_edit() -> impl Strategy<Value = TomlEdit> {
    prop_oneof![
        6 => (any::<prop::sample::Index>(), prop::sample::select(WILD_VALUES))
            .prop_map(|(i, v)| TomlEdit::Value(i, v)),
        1 => any::<prop::sample::Index>().prop_map(TomlEdit::DropLine),
        1 => any::<prop::sample::Index>().prop_map(TomlEdit::DuplicateLine),
        1 => (any::<prop::sample::Index>(), any::<u8>()).prop_map(|(i, b)| TomlEdit::Byte(i, b)),
    ]
}

/// `text` with `edits` applied in order.
fn mutate_toml(text: &str, edits: &[TomlEdit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for edit in edits {
        if lines.is_empty() {
            break;
        }
        match edit {
            TomlEdit::Value(index, value) => {
                let assignments: Vec<usize> = (0..lines.len())
                    .filter(|&i| !lines[i].trim_start().starts_with('#') && lines[i].contains('='))
                    .collect();
                if assignments.is_empty() {
                    continue;
                }
                let line = &mut lines[assignments[index.index(assignments.len())]];
                if let Some(at) = line.find('=') {
                    line.truncate(at + 1);
                    line.push(' ');
                    line.push_str(value);
                }
            }
            TomlEdit::DropLine(index) => {
                let at = index.index(lines.len());
                lines.remove(at);
            }
            TomlEdit::DuplicateLine(index) => {
                let at = index.index(lines.len());
                let line = lines[at].clone();
                lines.insert(at, line);
            }
            TomlEdit::Byte(index, byte) => {
                let mut bytes = lines.join("\n").into_bytes();
                if bytes.is_empty() {
                    continue;
                }
                let at = index.index(bytes.len());
                bytes[at] = *byte;
                lines = String::from_utf8_lossy(&bytes)
                    .lines()
                    .map(str::to_owned)
                    .collect();
            }
        }
    }
    lines.join("\n")
}

/// Writes `text` to a scratch file and returns its path (removed by the caller).
fn scratch_file(text: &str) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!(
        "harvest-settings-prop-{}-{}.toml",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&path, text).expect("write settings");
    path
}

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
    let path = scratch_file(&complete_settings());
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
        let path = scratch_file(&mutate_toml(&complete_settings(), &edits));
        let read = VacuumProcessConfig::from_path(&path);
        let _ = std::fs::remove_file(&path);
        match read {
            Ok(config) => run(&config)?,
            Err(error) => prop_assert!(!error.to_string().is_empty()),
        }
    }
}
