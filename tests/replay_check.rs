//! `harvest replay --check`: a stack (simulator, camera, perception with laser refinement, the
//! laser, both arms, the vacuum supervisor, and a recorder taking the camera raw) is recorded;
//! this build's perception, arms and vacuum supervisor are re-run on the recording and
//! compared with what the live processes decided. Checked: 0 differences, the same report
//! twice; with one parameter changed (perception's estimator, an arm's valve-request resend
//! period, the vacuum policy) the check fails and names the first differing message.

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

/// The figure before `label` in the report's line of `topic` ("  perception/apples  12 compared").
fn report_count(stdout: &str, topic: &str, label: &str) -> u64 {
    let line = stdout
        .lines()
        .find(|line| line.trim_start().starts_with(topic))
        .unwrap_or_else(|| panic!("no line for {topic}: {stdout}"));
    count_before(line, label)
}

/// The report's section of a control node: its lines from "check: NAME re-run" to the next
/// "check:" line.
fn control_section<'a>(stdout: &'a str, name: &str) -> Vec<&'a str> {
    let header = format!("check: {name} re-run on its ");
    let mut lines = stdout.lines().skip_while(|line| !line.starts_with(&header));
    let Some(first) = lines.next() else {
        panic!("no section for {name}: {stdout}")
    };
    std::iter::once(first)
        .chain(lines.take_while(|line| !line.starts_with("check:")))
        .collect()
}

/// The count in `line` before `label` ("  arm1/state  2400 compared, 2400 identical").
fn count_before(line: &str, label: &str) -> u64 {
    let words: Vec<&str> = line.split_whitespace().collect();
    let at = words
        .iter()
        .position(|word| word.trim_end_matches(',') == label)
        .unwrap_or_else(|| panic!("no {label:?} in {line:?}"));
    words[at - 1].parse().expect("a count")
}

#[test]
fn perception_arms_and_vacuum_rerun_on_their_recording_decide_the_same_and_a_changed_parameter_is_named()
 {
    let _stack = one_stack_at_a_time();
    let dir = TempDir::new("replaycheck");
    let raw_dir = dir.0.join("raw");
    // The recorder comes first so that it hears the camera's first frame and the control
    // nodes' first ticks.
    let launch = dir.write(
        "record.toml",
        &format!(
            "[[process]]\nname = \"recorder\"\ncommand = \"recorder\"\n\
             args = [\"--output-dir\", \"{raw}\", \"--camera\", \"raw\", \"--compression\", \"lz4\", \
             \"--include\", \"camera/*\", \"--include\", \"perception/*\", \"--include\", \"laser/*\", \
             \"--include\", \"arm1/*\", \"--include\", \"arm2/*\", \"--include\", \"vacuum/*\", \
             \"--include\", \"harvest/*\", \"--include\", \"operator/*\", \"--include\", \"safety/*\"]\n\n\
             [[process]]\nname = \"sim\"\ncommand = \"sim\"\nargs = [\"--camera-rate-hz\", \"5\"]\n\n\
             [[process]]\nname = \"camera\"\ncommand = \"camera\"\n\n\
             [[process]]\nname = \"perception\"\ncommand = \"perception\"\n\
             args = [\"--calibration\", \"{SIM_CAMERA_CALIBRATION}\", \"--laser-calibration\", \"{SIM_ALACS_CALIBRATION}\"]\n\n\
             [[process]]\nname = \"laser\"\ncommand = \"laser\"\nargs = [\"--calibration\", \"{SIM_ALACS_CALIBRATION}\"]\n\n\
             [[process]]\nname = \"arm1\"\ncommand = \"arm\"\nargs = [\"--id\", \"1\", \"--without-operator\"]\n\n\
             [[process]]\nname = \"arm2\"\ncommand = \"arm\"\nargs = [\"--id\", \"2\", \"--without-operator\"]\n\n\
             [[process]]\nname = \"vacuum\"\ncommand = \"vacuum\"\nargs = [\"--without-operator\"]\n",
            raw = raw_dir.display(),
        ),
    );
    run_up_for("rcheck", &launch, "15s", Duration::from_secs(120));
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
    let perception_part = first
        .split("check: arm1 re-run")
        .next()
        .expect("the report's start");
    assert!(!perception_part.contains("not re-run"), "{first}");
    assert!(stderr.contains("x real time"), "{stderr}");
    // Each control node re-ran from its first tick, and every channel it writes matched.
    for (name, channels) in [
        (
            "arm1",
            ["arm1/state", "arm1/command", "vacuum/valve_request"],
        ),
        (
            "arm2",
            ["arm2/state", "arm2/command", "vacuum/valve_request"],
        ),
        (
            "vacuum",
            ["vacuum/state", "arm1/target", "vacuum/valve_grant"],
        ),
    ] {
        let section = control_section(&first, name);
        let ticks = count_before(section[0], "recorded");
        assert!(ticks >= 1000, "{name}: {ticks} ticks re-run: {first}");
        for topic in channels {
            let line = section
                .iter()
                .find(|line| line.trim_start().starts_with(topic))
                .unwrap_or_else(|| panic!("{name}: no line for {topic}: {first}"));
            let compared = count_before(line, "compared");
            assert!(compared > 0, "{name}: nothing compared on {topic}: {first}");
            assert_eq!(count_before(line, "identical"), compared, "{first}");
        }
    }
    // This build's safety monitor, re-judging the recording, finds what the live stack
    // published (no monitor ran live, and the re-judged rules find nothing either).
    assert!(
        first.contains("check: the safety monitor's rules re-judged on the recording"),
        "{first}"
    );
    assert_eq!(
        report_count(&first, "safety/violation", "identical"),
        report_count(&first, "safety/violation", "compared"),
        "{first}"
    );
    // The vacuum supervisor assigned apples and the arms worked on them: the check covered
    // decisions, not only idle ticks.
    let events = control_section(&first, "vacuum")
        .into_iter()
        .find(|line| line.trim_start().starts_with("harvest/events"))
        .map_or(0, |line| count_before(line, "compared"));
    assert!(events > 0, "no vacuum event compared: {first}");

    let (code, second, stderr) = check(&recordings[0], &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(first, second, "two checks of one file differ");

    // One parameter changed: perception's estimator.
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

    // One parameter of arm 1 changed: its standing valve request is re-sent twice as often.
    let arm_config = dir.write("arm1.toml", "valve_request_resend_ms = 250\n");
    let (code, changed, stderr) = check(
        &recordings[0],
        &["--arm1-config", arm_config.to_str().expect("utf-8")],
    );
    assert_eq!(code, Some(1), "{changed}\n{stderr}");
    let arm1 = control_section(&changed, "arm1");
    let request = arm1
        .iter()
        .position(|line| line.trim_start().starts_with("vacuum/valve_request"))
        .unwrap_or_else(|| panic!("no valve requests for arm1: {changed}"));
    assert!(
        arm1[request..]
            .iter()
            .any(|line| line.contains("first difference")),
        "arm1's valve requests should differ: {changed}"
    );
    for topic in ["arm2/state", "vacuum/state"] {
        let line = changed
            .lines()
            .find(|line| line.trim_start().starts_with(topic))
            .unwrap_or_else(|| panic!("no {topic}: {changed}"));
        assert_eq!(
            count_before(line, "identical"),
            count_before(line, "compared"),
            "only arm 1's requests changed, not what the others decided from them: {changed}"
        );
    }

    // The vacuum policy changed: the supervisor's state names another policy from its first tick.
    let (code, changed, stderr) = check(&recordings[0], &["--vacuum-policy", "baseline"]);
    assert_eq!(code, Some(1), "{changed}\n{stderr}");
    let vacuum = control_section(&changed, "vacuum");
    assert!(
        vacuum
            .iter()
            .any(|line| line.contains("first difference") && line.contains("policy")),
        "{changed}"
    );
}
