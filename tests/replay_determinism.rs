//! Record-and-replay debugging: camera frames recorded from a running stack are replayed into a
//! stack without camera or simulator; perception re-runs on them, and two replays of the same
//! recording give the same detections for every frame both processed.

mod common;

use common::*;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

/// Detections per source frame (keyed by the frame's capture time), from `harvest rec cat`.
fn detections_by_frame(file: &Path) -> BTreeMap<u64, serde_json::Value> {
    let (status, stdout, stderr) = run_harvest(
        &unique_domain("cat"),
        &[
            "rec",
            "cat",
            file.to_str().expect("utf-8"),
            "--topic",
            "perception/apples",
        ],
        Duration::from_secs(60),
    );
    assert!(status.success(), "{stderr}");
    let mut by_frame = BTreeMap::new();
    for line in stdout.lines().filter(|l| !l.trim().is_empty()) {
        let record: serde_json::Value = serde_json::from_str(line).expect("JSON line");
        let message = record.get("message").unwrap_or(&record);
        let capture_ns = message["source_capture_ns"]
            .as_u64()
            .expect("source_capture_ns");
        by_frame.insert(capture_ns, message["apples"].clone());
    }
    by_frame
}

fn replay_into_perception(
    recording: &Path,
    dir: &TempDir,
    run: u32,
) -> BTreeMap<u64, serde_json::Value> {
    let out_dir = dir.0.join(format!("out{run}"));
    let launch = dir.write(
        &format!("perception{run}.toml"),
        &format!(
            "[[process]]\nname = \"perception\"\ncommand = \"perception\"\n\
             args = [\"--calibration\", \"{SIM_CAMERA_CALIBRATION}\"]\n\n[[process]]\nname = \"recorder\"\n\
             command = \"recorder\"\nargs = [\"--output-dir\", \"{}\", \"--include\", \"perception/*\"]\n",
            out_dir.display()
        ),
    );
    let domain = unique_domain(&format!("rp{run}"));
    let stack = spawn_harvest(
        &domain,
        &[
            "up",
            "--launch",
            launch.to_str().expect("utf-8"),
            "--duration",
            "25s",
        ],
    );
    std::thread::sleep(Duration::from_secs(4));
    let (status, _, stderr) = run_harvest(
        &domain,
        &[
            "replay",
            recording.to_str().expect("utf-8"),
            "--include",
            "camera/rgbd",
            "--rate",
            "0.5",
            "--no-keyboard",
        ],
        Duration::from_secs(120),
    );
    assert!(status.success(), "replay failed: {stderr}");
    let (status, _, stderr) = wait_with_watchdog(stack, Duration::from_secs(120));
    assert!(status.success(), "{stderr}");
    assert_eq!(leftover_files(&domain), "");
    let files = mcap_files(&out_dir);
    assert_eq!(files.len(), 1, "{files:?}");
    detections_by_frame(&files[0])
}

#[test]
fn replayed_frames_rerun_perception_deterministically() {
    let _stack = one_stack_at_a_time();
    let dir = TempDir::new("replay");
    let record_dir = dir.0.join("recorded");
    let launch = dir.write(
        "record.toml",
        &format!(
            "[[process]]\nname = \"sim\"\ncommand = \"sim\"\nargs = [\"--camera-rate-hz\", \"5\"]\n\n\
             [[process]]\nname = \"camera\"\ncommand = \"camera\"\n\n[[process]]\nname = \"recorder\"\n\
             command = \"recorder\"\nargs = [\"--output-dir\", \"{}\", \"--include\", \"camera/*\"]\n",
            record_dir.display()
        ),
    );
    run_up_for("rec", &launch, "5s", Duration::from_secs(90));
    let recordings = mcap_files(&record_dir);
    assert_eq!(recordings.len(), 1, "{recordings:?}");

    let first = replay_into_perception(&recordings[0], &dir, 1);
    let second = replay_into_perception(&recordings[0], &dir, 2);
    let common: Vec<&u64> = first.keys().filter(|k| second.contains_key(*k)).collect();
    assert!(
        common.len() >= 5,
        "too few frames processed in both runs: {} / {}",
        first.len(),
        second.len()
    );
    let mut apples_seen = 0;
    for capture_ns in common {
        assert_eq!(
            first[capture_ns], second[capture_ns],
            "frame {capture_ns} differs between replays"
        );
        apples_seen += first[capture_ns].as_array().map_or(0, Vec::len);
    }
    assert!(
        apples_seen > 0,
        "perception found no apples in the replayed frames"
    );
}
