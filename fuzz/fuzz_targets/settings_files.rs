//! Any text as each settings file (the first byte picks which): the launch file, a scenario,
//! perception's configuration and calibration, the arm and vacuum settings (then the node they
//! configure is built), the laser calibration file. Every failure must name the file.
#![no_main]

use harvest_arm::node::ArmNode;
use harvest_arm_process::ArmDevice;
use harvest_arm_process::process::ArmProcessConfig;
use harvest_perception::calibration::Calibration;
use harvest_perception::config_file::parse_config;
use harvest_robot_model::ArmId as VacuumArm;
use harvest_robot_model::params::ArmId;
use harvest_sim::scenario::Scenario;
use harvest_supervisor::launch::Launch;
use harvest_vacuum::node::{VacuumNode, VacuumNodeConfig};
use harvest_vacuum_process::process::VacuumProcessConfig;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fn named(error: impl std::fmt::Display, name: &str) {
    let message = error.to_string();
    assert!(message.contains(name), "error does not name {name}: {message}");
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("harvest-fuzz-settings-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let file = dir.join("fuzzed.toml");
    match pick % 7 {
        0 => {
            if let Err(error) = Launch::parse_in(text, "fuzzed.toml", Path::new("/launch")) {
                named(error, "fuzzed.toml");
            }
        }
        1 => match Scenario::from_toml_str("fuzzed.toml", text) {
            Ok(scenario) => {
                let _ = scenario.camera.robot_from_camera();
            }
            Err(error) => named(error, "fuzzed.toml"),
        },
        2 => {
            if let Err(error) = parse_config(text, "fuzzed.toml") {
                named(error, "fuzzed.toml");
            }
        }
        3 => {
            if let Err(error) = Calibration::parse(text, "fuzzed.toml") {
                named(error, "fuzzed.toml");
            }
        }
        4 => {
            std::fs::write(&file, text).expect("write");
            if let Ok(config) = ArmProcessConfig::from_path(&file) {
                let _ = ArmNode::new(
                    ArmId::Arm1,
                    config.node.unwrap_or(ArmDevice::Sim.node_config()),
                );
            }
        }
        5 => {
            std::fs::write(&file, text).expect("write");
            if let Ok(config) = VacuumProcessConfig::from_path(&file) {
                let _ = VacuumNode::new(
                    config.node.unwrap_or(VacuumNodeConfig::default()),
                    Box::new(|_: VacuumArm, _: &[f64; 3], _: f64| true),
                );
            }
        }
        _ => {
            std::fs::write(&file, text).expect("write");
            if let Err(error) = harvest_laser::calibration::read_calibration_file(&file) {
                named(error, "fuzzed.toml");
            }
        }
    }
});
