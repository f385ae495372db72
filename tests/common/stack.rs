//! Pieces of the whole-stack tests: the small orchards, the picking stack's launch file, the
//! Python readers they check files with, a process's private memory.

use super::SIM_CAMERA_CALIBRATION;
use std::process::Command;

/// The `ideal` preset (a grid, no occlusion) with `apples` apples and every seal failing with
/// probability `seal_failure`.
pub fn ideal_orchard(apples: u32, seal_failure: f64) -> String {
    let ideal = include_str!("../../sim/scenarios/ideal.toml");
    assert!(
        ideal.contains("count = 16") && ideal.contains("seal_failure = 0.0"),
        "the ideal preset changed"
    );
    ideal
        .replace("count = 16", &format!("count = {apples}"))
        .replace(
            "seal_failure = 0.0",
            &format!("seal_failure = {seal_failure:?}"),
        )
}

/// A launch file of the simulator (10 frames/s) and both arms without an executive, with the
/// camera, perception and the vacuum when `with_vision`; `extra` (more `[[process]]` blocks)
/// is appended.
pub fn picking_launch(scenario: &str, with_vision: bool, extra: &str) -> String {
    let mut text = format!(
        r#"
[stack]
hang_timeout_ms = 5000
shutdown_grace_ms = 5000
startup_grace_ms = 15000

[[process]]
name = "sim"
command = "sim"
args = ["--scenario", "{scenario}", "--seed", "1", "--camera-rate-hz", "10"]
restart = "never"

[[process]]
name = "arm1"
command = "arm"
args = ["--id", "1", "--without-operator"]
restart = "never"

[[process]]
name = "arm2"
command = "arm"
args = ["--id", "2", "--without-operator"]
restart = "never"
"#
    );
    if with_vision {
        text.push_str(&format!(
            r#"
[[process]]
name = "camera"
command = "camera"
restart = "never"

[[process]]
name = "perception"
command = "perception"
args = ["--calibration", "{SIM_CAMERA_CALIBRATION}"]
restart = "never"

[[process]]
name = "vacuum"
command = "vacuum"
args = ["--policy", "2024", "--arms", "2", "--without-operator"]
restart = "never"
"#
        ));
    }
    text.push_str(extra);
    text
}

/// Makes sure `python3` imports `modules`, installing `packages` with pip when it does not.
pub fn ensure_python(modules: &str, packages: &[&str]) {
    let available = || {
        Command::new("python3")
            .args(["-c", &format!("import {modules}")])
            .status()
            .is_ok_and(|status| status.success())
    };
    if !available() {
        let _ = Command::new("python3")
            .args(["-m", "pip", "install", "--quiet"])
            .args(packages)
            .status();
    }
    assert!(
        available(),
        "python3 with {modules} is required (pip install {})",
        packages.join(" ")
    );
}

/// The official Python MCAP reader with both chunk compressions the recorder writes.
pub fn ensure_python_mcap() {
    ensure_python("mcap, lz4, zstandard", &["mcap", "lz4", "zstandard"]);
}

/// Private memory of a process (`RssAnon`: heap, stacks), bytes.
pub fn rss_anon_bytes(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .expect("status")
        .lines()
        .find_map(|line| line.strip_prefix("RssAnon:"))
        .and_then(|rest| {
            rest.trim()
                .trim_end_matches("kB")
                .trim()
                .parse::<u64>()
                .ok()
        })
        .expect("RssAnon")
        * 1024
}
