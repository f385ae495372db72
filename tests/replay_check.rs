//! `harvest replay --check`: a stack (simulator, camera, perception with laser refinement, the
//! laser, and a recorder taking the camera raw) is recorded; this build's perception is re-run
//! on the recording and compared with what the live process decided. Checked: 0 differences,
//! the same report twice; with one parameter changed (a config override) the check fails and
//! names the first differing message.

mod common;

use common::*;
use std::path::Path;
use std::time::Duration;

const SIM_ALACS_CALIBRATION: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/sim/alacs_calibration.toml");

/// `harvest replay --check` on `recording` with perception's arguments as it ran, and `extra`.
fn check(recording: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec![
        "replay",
        "--check",
        recording.to_str().expect("utf-8"),
        "--calibration",
        SIM_CAMERA_CALIBRATION,
        "--laser-calibration",
        SIM_ALACS_CALIBRATION,
    ];
    args.extend_from_slice(extra);
    let (status, stdout, stderr) =
        run_harvest(&unique_domain("check"), &args, Duration::from_secs(300));
    (status.code(), stdout, stderr)
}

/// The figure after `label` in the report's line of `topic` ("  perception/apples  12 compared").
fn report_count(stdout: &str, topic: &str, label: &str) -> u64 {
    let line = stdout
        .lines()
        .find(|line| line.trim_start().starts_with(topic))
        .unwrap_or_else(|| panic!("no line for {topic}: {stdout}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words
        .iter()
        .position(|word| word.trim_end_matches(',') == label)
        .unwrap_or_else(|| panic!("no {label:?} in {line:?}"));
    words[at - 1].parse().expect("a count")
}

#[test]
fn perception_rerun_on_its_recording_decides_the_same_and_a_changed_parameter_is_named() {
    let _stack = one_stack_at_a_time();
    let dir = TempDir::new("replaycheck");
    let raw_dir = dir.0.join("raw");
    // The recorder comes first so that it hears the camera's first frame.
    let launch = dir.write(
        "record.toml",
        &format!(
            "[[process]]\nname = \"recorder\"\ncommand = \"recorder\"\n\
             args = [\"--output-dir\", \"{raw}\", \"--camera\", \"raw\", \"--compression\", \"lz4\", \
             \"--include\", \"camera/*\", \"--include\", \"perception/*\", \"--include\", \"laser/*\"]\n\n\
             [[process]]\nname = \"sim\"\ncommand = \"sim\"\nargs = [\"--camera-rate-hz\", \"5\"]\n\n\
             [[process]]\nname = \"camera\"\ncommand = \"camera\"\n\n\
             [[process]]\nname = \"perception\"\ncommand = \"perception\"\n\
             args = [\"--calibration\", \"{SIM_CAMERA_CALIBRATION}\", \"--laser-calibration\", \"{SIM_ALACS_CALIBRATION}\"]\n\n\
             [[process]]\nname = \"laser\"\ncommand = \"laser\"\nargs = [\"--calibration\", \"{SIM_ALACS_CALIBRATION}\"]\n",
            raw = raw_dir.display(),
        ),
    );
    run_up_for("rcheck", &launch, "12s", Duration::from_secs(120));
    let recordings = mcap_files(&raw_dir);
    assert_eq!(recordings.len(), 1, "{recordings:?}");

    let (code, first, stderr) = check(&recordings[0], &[]);
    assert_eq!(code, Some(0), "{first}\n{stderr}");
    assert!(first.contains("check: identical"), "{first}");
    let compared = report_count(&first, "perception/apples", "compared");
    assert!(compared >= 10, "too few frames re-run: {first}");
    assert_eq!(
        report_count(&first, "perception/apples", "identical"),
        compared,
        "{first}"
    );
    assert!(!first.contains("not re-run"), "{first}");
    assert!(stderr.contains("x real time"), "{stderr}");

    let (code, second, stderr) = check(&recordings[0], &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(first, second, "two checks of one file differ");

    // One parameter changed: the estimator.
    let config = dir.write("cluster.toml", "[estimator]\nkind = \"cluster_depth\"\n");
    let (code, changed, stderr) = check(
        &recordings[0],
        &["--config", config.to_str().expect("utf-8")],
    );
    assert_eq!(code, Some(1), "{changed}\n{stderr}");
    assert!(changed.contains("check: DIFFERENT"), "{changed}");
    let difference = changed
        .lines()
        .find(|line| line.contains("first difference"))
        .unwrap_or_else(|| panic!("no difference named: {changed}"));
    assert!(
        difference.contains("apples[")
            && difference.contains("recorded")
            && difference.contains("re-run"),
        "{difference}"
    );
}
