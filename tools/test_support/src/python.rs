//! The independent Python checkers the tests run (the official `mcap` reader, `rosbags`,
//! `eclipse-zenoh`, ONNX Runtime, `crcmod`...): one way to make sure they are importable,
//! installing the missing ones with pip as `.ci/run` does.

use std::path::Path;
use std::process::Command;

/// Makes sure `python3` imports every module of `modules` (comma-separated, as after `import`),
/// installing `packages` with pip when it does not; panics naming the command to run by hand.
pub fn ensure_python(modules: &str, packages: &[&str]) {
    let importable = || {
        Command::new("python3")
            .args(["-c", &format!("import {modules}")])
            .status()
            .is_ok_and(|status| status.success())
    };
    if !importable() {
        // The result is what the second import says: pip's own failure adds nothing to it.
        let _ = Command::new("python3")
            .args(["-m", "pip", "install", "--quiet"])
            .args(packages)
            .status();
    }
    assert!(
        importable(),
        "python3 with `{modules}` is required (python3 -m pip install {})",
        packages.join(" ")
    );
}

/// The official Python MCAP reader with both chunk compressions the recorder writes.
pub fn ensure_python_mcap() {
    ensure_python("mcap, lz4, zstandard", &["mcap", "lz4", "zstandard"]);
}

/// Runs `script` with `python3 -c` on `path` and parses what it prints as JSON; panics with
/// the script's error output when it fails (the independent readers the tests check files with).
pub fn python_json(script: &str, path: &Path) -> serde_json::Value {
    let output = Command::new("python3")
        .args(["-c", script])
        .arg(path)
        .output()
        .expect("run python3");
    assert!(
        output.status.success(),
        "the Python reader failed on {}: {}",
        path.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("the Python reader prints JSON")
}
