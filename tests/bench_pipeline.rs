//! `harvest bench pipeline` against a real stack (it starts `harvest up` with its own launch
//! file in a domain of its own): the JSON report and the plot are well formed, every hop is
//! present (measured or "no data"), and the stack's resources are gone afterwards. No timing is
//! asserted.

mod common;

use common::*;
use serde_json::Value;
use std::time::Duration;

const HOPS: [&str; 7] = [
    "camera-publish",
    "device-frame",
    "driver-frame",
    "perception-result",
    "perception-processing",
    "arm-target",
    "arm-command",
];
const END_TO_END: [&str; 2] = ["capture-to-detections", "capture-to-command"];
const TOPICS: [&str; 10] = [
    "hw/camera/rgbd",
    "camera/rgbd",
    "perception/apples",
    "arm1/target",
    "arm2/target",
    "arm1/command",
    "arm2/command",
    "arm1/state",
    "arm2/state",
    "vacuum/state",
];

fn u64_field(value: &Value, key: &str) -> u64 {
    value[key]
        .as_u64()
        .unwrap_or_else(|| panic!("{key} missing or not an integer in {value}"))
}

/// A stage entry is either a latency distribution with ordered percentiles, or null latency
/// with a "no data" note. Returns whether it had data.
fn check_stage(stage: &Value) -> bool {
    if stage["latency"].is_null() {
        assert!(
            stage["note"]
                .as_str()
                .is_some_and(|note| note.starts_with("no data")),
            "{stage}"
        );
        return false;
    }
    let latency = &stage["latency"];
    assert!(u64_field(latency, "samples") >= 1, "{stage}");
    let percentiles: Vec<u64> = ["p50_ns", "p90_ns", "p99_ns", "max_ns"]
        .iter()
        .map(|key| u64_field(latency, key))
        .collect();
    assert!(
        percentiles.windows(2).all(|w| w[0] <= w[1]),
        "{percentiles:?}"
    );
    assert!(stage["note"].is_null(), "{stage}");
    true
}

fn stage_names(report: &Value, key: &str) -> Vec<String> {
    report[key]
        .as_array()
        .unwrap_or_else(|| panic!("{key} missing"))
        .iter()
        .map(|stage| stage["stage"].as_str().expect("stage name").to_owned())
        .collect()
}

fn check_report_shape(report: &Value) {
    assert_eq!(report["tool"], "harvest bench pipeline");
    assert_eq!(stage_names(report, "hops"), HOPS);
    assert_eq!(stage_names(report, "end_to_end"), END_TO_END);
    let control_loop = report["control_loop"].as_array().expect("control_loop");
    let channels: Vec<&str> = control_loop
        .iter()
        .map(|j| j["channel"].as_str().expect("channel"))
        .collect();
    assert_eq!(
        channels,
        [
            "arm1/command",
            "arm1/state",
            "arm2/command",
            "arm2/state",
            "vacuum/state"
        ]
    );
    for jitter in control_loop {
        assert_eq!(u64_field(jitter, "nominal_period_ns"), 5_000_000);
        assert_eq!(
            jitter["deviation"].is_null(),
            u64_field(jitter, "periods") == 0,
            "{jitter}"
        );
    }
    let topics: Vec<&str> = report["channels"]
        .as_array()
        .expect("channels")
        .iter()
        .map(|c| c["topic"].as_str().expect("topic"))
        .collect();
    assert_eq!(topics, TOPICS);
}

#[test]
fn pipeline_bench_measures_a_real_stack_and_writes_json_and_svg() {
    let _stack = one_stack_at_a_time();
    let dir = TempDir::new("bench-pipeline");
    let json = dir.0.join("pipeline.json");
    let svg = dir.0.join("pipeline.svg");
    let domain = unique_domain("bpt");
    let (status, stdout, stderr) = run_harvest(
        &domain,
        &[
            "bench",
            "pipeline",
            "--duration",
            "3s",
            "--warmup",
            "3s",
            "--load",
            "1",
            "--json",
            json.to_str().expect("utf-8 path"),
            "--svg",
            svg.to_str().expect("utf-8 path"),
        ],
        Duration::from_secs(90),
    );
    assert!(
        status.success(),
        "bench pipeline failed:\n{stdout}\n{stderr}"
    );
    assert!(
        stdout.contains("per hop")
            && stdout.contains("end to end")
            && stdout.contains("200 Hz control loops")
            && stdout.contains("control loops side by side"),
        "{stdout}"
    );

    let runs: Value = serde_json::from_str(&std::fs::read_to_string(&json).expect("json written"))
        .expect("valid JSON");
    let runs = runs["runs"].as_array().expect("runs");
    // By default: the launch file's scheduling, then the same stack without it.
    let schedulings: Vec<&str> = runs
        .iter()
        .map(|run| run["scheduling"].as_str().expect("scheduling"))
        .collect();
    assert_eq!(schedulings, ["as_launched", "without"]);
    for run in runs {
        check_report_shape(run);
        assert_eq!(run["settings"]["load_threads"], 1);
    }
    assert_ne!(
        runs[0]["domain"], runs[1]["domain"],
        "each run in a fresh domain"
    );
    let report = &runs[0];
    // The scheduled run's supervisor applied (or, on a machine that forbids it, warned about)
    // the bench launch file's real-time settings.
    let scheduled_log =
        std::fs::read_to_string(report["stack_log"].as_str().expect("log")).expect("stack log");
    assert!(scheduled_log.contains("scheduling"), "{scheduled_log}");
    assert_eq!(report["settings"]["attached"], false);
    assert_eq!(report["interrupted"], false);
    // The bench ran the stack in a domain of its own, not the test's.
    let bench_domain = report["domain"].as_str().expect("domain");
    assert_ne!(bench_domain, &*domain);

    let hops = report["hops"].as_array().expect("hops");
    let with_data: Vec<bool> = hops.iter().map(check_stage).collect();
    for stage in report["end_to_end"].as_array().expect("end_to_end") {
        check_stage(stage);
    }
    // The camera publishes from the start: its hop always has frames to measure.
    assert!(
        with_data[0],
        "no camera frames measured:\n{stdout}\n{stderr}"
    );
    let frames = &report["channels"][1];
    assert!(u64_field(frames, "received") >= 1);

    // The stack was stopped and its domain removed.
    assert_eq!(
        report["leftover_files"].as_array().map(Vec::len),
        Some(0),
        "{report}"
    );
    assert_eq!(leftover_files(bench_domain), "", "iceoryx2 files left");
    for run in runs {
        let log = run["stack_log"].as_str().expect("stack log path");
        let text = std::fs::read_to_string(log).expect("stack log");
        assert!(text.contains("harvest up ended"), "{text}");
        let _ = std::fs::remove_file(log);
    }

    let plot = std::fs::read_to_string(&svg).expect("svg written");
    assert!(plot.starts_with("<svg") && plot.trim_end().ends_with("</svg>"));
    assert_eq!(
        plot.matches("<rect").count() - 1 + plot.matches(">no data<").count(),
        HOPS.len() + END_TO_END.len(),
        "one bar or 'no data' per stage:\n{plot}"
    );
}

#[test]
fn attached_to_an_empty_domain_every_hop_is_no_data() {
    let dir = TempDir::new("bench-pipeline-attach");
    let json = dir.0.join("attached.json");
    let domain = unique_domain("bpe");
    let (status, stdout, stderr) = run_harvest(
        &domain,
        &[
            "bench",
            "pipeline",
            "--attach",
            "--duration",
            "300ms",
            "--warmup",
            "0s",
            "--json",
            json.to_str().expect("utf-8 path"),
        ],
        Duration::from_secs(30),
    );
    assert!(status.success(), "bench pipeline failed:\n{stderr}");
    let runs: Value = serde_json::from_str(&std::fs::read_to_string(&json).expect("json written"))
        .expect("valid JSON");
    let runs = runs["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 1, "attached: one run of what is running");
    let report = &runs[0];
    assert_eq!(report["scheduling"], "attached");
    check_report_shape(report);
    assert_eq!(report["settings"]["attached"], true);
    assert_eq!(report["domain"], &*domain);
    for stage in report["hops"]
        .as_array()
        .expect("hops")
        .iter()
        .chain(report["end_to_end"].as_array().expect("end_to_end"))
    {
        assert!(!check_stage(stage), "{stage}");
    }
    assert!(stdout.contains("no data"), "{stdout}");
    assert_eq!(leftover_files(&domain), "", "iceoryx2 files left");
}
