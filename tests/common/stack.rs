//! Pieces of the whole-stack tests: the small orchards, the picking stack's launch file, the
//! Python readers they check files with, a process's private memory.

use super::SIM_CAMERA_CALIBRATION;
#[allow(unused_imports)]
pub use harvest_test_support::python::{ensure_python, ensure_python_mcap, python_json};
use std::path::{Path, PathBuf};

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

/// Private memory of a process (`RssAnon`: heap, stacks), bytes.
pub fn rss_anon_bytes(pid: u32) -> u64 {
    harvest_ipc::proc_status::process_status_field(pid, "RssAnon:").expect("RssAnon") * 1024
}

/// The `.mcap` files in `dir`, sorted by name (none when `dir` does not exist).
pub fn mcap_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| entries.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.retain(|p| p.extension().is_some_and(|e| e == "mcap"));
    files.sort();
    files
}
