//! Property test of the arm settings reader (issue 18, item 3): a complete settings file (with
//! its `[node]` table) with values replaced by anything (NaN, negative, huge, wrongly typed),
//! lines dropped or doubled and bytes changed. The file is refused with an error naming it, or
//! the node it configures is refused, or that node drives its arm to a target with set-points
//! that are finite and inside the Table 1 joint limits; never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed setup is a failed test

use harvest_arm::node::{ArmNode, ArmNodeConfig, ArmNodeInput, EncoderSample, ServoOrder};
use harvest_arm_process::ArmDevice;
use harvest_arm_process::process::ArmProcessConfig;
use harvest_ipc::payloads::{ArmTarget, VacuumState};
use harvest_robot_model::params::{ArmId, ArmParams};
use proptest::prelude::*;
use std::path::PathBuf;

/// Cases: each reads one file and runs up to 300 control periods.
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
    let path = scratch_file(&complete_settings());
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
        let path = scratch_file(&mutate_toml(&complete_settings(), &edits));
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
