//! `bench ipc --quick` across real processes (the bench binary spawns itself as the sending
//! peer): the JSON report and the SVG plot are well formed and complete. No timing is asserted.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_harvest-bench-peer");
const CATALOGUE_PAYLOADS: [&str; 3] = ["scan-request", "detections", "rgbd"];
const TRANSPORTS: [&str; 3] = ["ours", "iceoryx2", "uds-copy"];
const MODES: [&str; 2] = ["event", "poll"];

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("harvest-bench-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

fn u64_field(value: &Value, key: &str) -> u64 {
    value[key]
        .as_u64()
        .unwrap_or_else(|| panic!("{key} missing or not an integer in {value}"))
}

fn f64_field(value: &Value, key: &str) -> f64 {
    value[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing or not a number in {value}"))
}

/// Every opening tag is closed in order (self-closing tags count as both).
fn assert_balanced_tags(svg: &str) {
    let mut open = Vec::new();
    for piece in svg.split('<').skip(1) {
        let tag = &piece[..piece.find('>').expect("tag ends with >")];
        let name: String = tag
            .trim_start_matches('/')
            .chars()
            .take_while(|c| c.is_alphanumeric())
            .collect();
        if tag.starts_with('/') {
            assert_eq!(
                open.pop().as_deref(),
                Some(name.as_str()),
                "unbalanced </{name}>"
            );
        } else if !tag.ends_with('/') {
            open.push(name);
        }
    }
    assert!(open.is_empty(), "unclosed tags {open:?}");
}

fn domain_files(domain: &str) -> Vec<PathBuf> {
    let prefix = format!("hv_{domain}_");
    std::fs::read_dir("/dev/shm")
        .map(|entries| {
            entries
                .flatten()
                .filter(|entry| entry.file_name().to_string_lossy().starts_with(&prefix))
                .map(|entry| entry.path())
                .collect()
        })
        .unwrap_or_default()
}

fn run_quick(json: &Path, svg: &Path) -> std::process::Output {
    Command::new(EXE)
        .args([
            "bench",
            "ipc",
            "--quick",
            "--iterations",
            "20",
            "--duration",
            "100ms",
            "--transports",
            "ours,iceoryx2,uds-copy",
        ])
        .arg("--json")
        .arg(json)
        .arg("--svg")
        .arg(svg)
        .output()
        .expect("run the benchmark binary")
}

#[test]
fn quick_run_across_processes_reports_every_transport_and_size() {
    let dir = scratch_dir("quick");
    let (json_path, svg_path) = (dir.join("bench.json"), dir.join("bench.svg"));
    let output = run_quick(&json_path, &svg_path);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "benchmark failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains("p50 us") && stdout.contains("ratios") && stdout.contains("targets"));

    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).expect("json written"))
            .expect("valid JSON");
    assert_eq!(report["tool"], "harvest bench ipc");
    let settings = &report["settings"];
    assert_eq!(u64_field(settings, "iterations"), 20);
    assert_eq!(settings["quick"], true);
    let repeats = u64_field(settings, "repeats") as usize;
    assert!(u64_field(&report["host"], "cpus") >= 1);
    let payloads: Vec<&str> = settings["payloads"]
        .as_array()
        .expect("payloads")
        .iter()
        .map(|p| p.as_str().expect("payload name"))
        .collect();
    assert_eq!(payloads.len(), 11, "quick measures the default payload set");
    for expected in [
        "64B", "1KiB", "16KiB", "256KiB", "1MiB", "4MiB", "8MiB", "16MiB",
    ] {
        assert!(
            payloads.contains(&expected),
            "{expected} missing from {payloads:?}"
        );
    }
    for expected in CATALOGUE_PAYLOADS {
        assert!(
            payloads.contains(&expected),
            "{expected} missing from {payloads:?}"
        );
    }

    let results = report["results"].as_array().expect("results");
    assert_eq!(
        results.len(),
        payloads.len() * TRANSPORTS.len() * MODES.len()
    );
    for payload in &payloads {
        for transport in TRANSPORTS {
            for mode in MODES {
                let matching: Vec<&Value> = results
                    .iter()
                    .filter(|r| {
                        r["payload"] == *payload && r["transport"] == transport && r["mode"] == mode
                    })
                    .collect();
                assert_eq!(matching.len(), 1, "{payload}/{transport}/{mode}");
                let result = matching[0];
                // Our layer carries the sweep sizes on ad-hoc channels: every case is measured.
                assert_eq!(result["measured"], true, "{payload}/{transport}/{mode}");
                let size = u64_field(result, "size_bytes");
                match *payload {
                    "64B" | "scan-request" => assert_eq!(size, 64),
                    "16MiB" => assert_eq!(size, 16 << 20),
                    "rgbd" => assert!((6_500_000..7_000_000).contains(&size)),
                    _ => assert!(size > 0),
                }
                let latency = &result["latency"];
                let samples = u64_field(latency, "samples");
                assert!(
                    (1..=20).contains(&samples),
                    "{payload}/{transport}/{mode}: {samples}"
                );
                let percentiles: Vec<u64> = ["p50_ns", "p90_ns", "p99_ns", "p999_ns", "max_ns"]
                    .iter()
                    .map(|key| u64_field(latency, key))
                    .collect();
                assert!(percentiles[0] > 0);
                assert!(
                    percentiles.windows(2).all(|w| w[0] <= w[1]),
                    "{percentiles:?}"
                );
                let throughput = &result["throughput"];
                assert!(u64_field(throughput, "received") >= 1);
                // The stream's window fits the subscriber buffer: nothing may be overwritten.
                assert_eq!(
                    u64_field(throughput, "dropped"),
                    0,
                    "{payload}/{transport}/{mode}"
                );
                assert!(f64_field(throughput, "msgs_per_s") > 0.0);
                let expected_mb = f64_field(throughput, "msgs_per_s") * size as f64 / 1e6;
                assert!(
                    (f64_field(throughput, "mb_per_s") - expected_mb).abs() <= 1e-6 * expected_mb
                );
                assert_eq!(result["runs"].as_array().expect("runs").len(), repeats);
            }
        }
    }

    let ratios = report["ratios"].as_array().expect("ratios");
    for comparison in [
        "ours / raw iceoryx2",
        "copy / ours",
        "copy / raw iceoryx2",
        "RGB-D frame / 64 B",
    ] {
        assert!(
            ratios.iter().any(|r| r["comparison"] == comparison),
            "{comparison} missing"
        );
    }
    for ratio in ratios {
        assert!(
            f64_field(ratio, "p50") > 0.0 && f64_field(ratio, "p99") > 0.0,
            "{ratio}"
        );
    }
    let targets = report["targets"].as_array().expect("targets");
    assert_eq!(targets.len(), 2 * 8, "8 target checks per mode");
    for target in targets {
        let (value, limit) = (f64_field(target, "value"), f64_field(target, "limit"));
        let at_most = target["target"]
            .as_str()
            .is_some_and(|t| !t.contains("at least"));
        assert_eq!(
            target["met"],
            if at_most {
                value <= limit
            } else {
                value >= limit
            },
            "{target}"
        );
    }

    // Every iceoryx2 resource of the run's domain is gone, its global segment included.
    assert_eq!(report["leftover_files"].as_array().map(Vec::len), Some(0));
    let domain = report["domain"].as_str().expect("domain");
    assert!(
        domain_files(domain).is_empty(),
        "left in /dev/shm: {:?}",
        domain_files(domain)
    );

    let svg = std::fs::read_to_string(&svg_path).expect("svg written");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_balanced_tags(&svg);
    assert_eq!(
        svg.matches("<polyline").count(),
        TRANSPORTS.len() * MODES.len()
    );
    for transport in TRANSPORTS {
        for mode in MODES {
            assert!(
                svg.contains(&format!("{transport} ({mode})")),
                "legend {transport} ({mode})"
            );
        }
    }
    std::fs::remove_dir_all(&dir).expect("remove scratch dir");
}

#[test]
fn unknown_size_is_rejected_with_the_supported_list() {
    let output = Command::new(EXE)
        .args(["bench", "ipc", "--quick", "--sizes", "64,3K"])
        .output()
        .expect("run the benchmark binary");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("\"3K\"") && stderr.contains("16MiB"),
        "{stderr}"
    );
}

#[test]
fn peer_without_a_measuring_process_fails_naming_the_socket() {
    let control = scratch_dir("peer").join("missing.sock");
    let output = Command::new(EXE)
        .args([
            "bench-peer",
            "--domain",
            "bench-test-peer",
            "--transport",
            "ours",
        ])
        .args([
            "--mode",
            "event",
            "--payload",
            "rgbd",
            "--warmup",
            "1",
            "--iterations",
            "1",
        ])
        .args(["--duration", "10ms", "--control"])
        .arg(&control)
        .output()
        .expect("run the peer");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("missing.sock"), "{stderr}");
    assert!(domain_files("bench-test-peer").is_empty());
}

#[cfg(not(feature = "zenoh"))]
#[test]
fn zenoh_transports_without_the_feature_say_how_to_build_them() {
    let output = Command::new(EXE)
        .args(["bench", "ipc", "--quick", "--transports", "ours,zenoh-shm"])
        .output()
        .expect("run the benchmark binary");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("zenoh-shm") && stderr.contains("--features harvest-bench/zenoh"),
        "{stderr}"
    );
}

/// Both Zenoh peers across real processes, on the smallest message and the RGB-D frame: every
/// case measured, nothing lost in the stream, the peer ratios reported.
#[cfg(feature = "zenoh")]
#[test]
fn zenoh_peers_across_processes_are_measured_side_by_side_with_ours() {
    let dir = scratch_dir("zenoh");
    let json_path = dir.join("bench.json");
    let output = Command::new(EXE)
        .args(["bench", "ipc", "--quick", "--iterations", "20"])
        .args(["--duration", "100ms", "--sizes", "64B,rgbd"])
        .args(["--transports", "ours,zenoh-tcp,zenoh-shm", "--json"])
        .arg(&json_path)
        .output()
        .expect("run the benchmark binary");
    assert!(
        output.status.success(),
        "benchmark failed:\n{}\n{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    let report: Value =
        serde_json::from_str(&std::fs::read_to_string(&json_path).expect("json written"))
            .expect("valid JSON");
    let results = report["results"].as_array().expect("results");
    assert_eq!(results.len(), 2 * 3 * MODES.len());
    for result in results {
        assert_eq!(result["measured"], true, "{result}");
        assert!(u64_field(&result["latency"], "samples") >= 1, "{result}");
        assert_eq!(u64_field(&result["throughput"], "dropped"), 0, "{result}");
    }
    let ratios = report["ratios"].as_array().expect("ratios");
    for (comparison, numerator) in [
        ("zenoh-shm / ours", "zenoh-shm@rgbd"),
        ("zenoh-tcp / ours", "zenoh-tcp@64B"),
        ("RGB-D frame / 64 B", "zenoh-shm@rgbd"),
        ("RGB-D frame / 64 B", "zenoh-tcp@rgbd"),
    ] {
        assert!(
            ratios
                .iter()
                .any(|r| r["comparison"] == comparison && r["numerator"] == numerator),
            "{comparison} {numerator} missing"
        );
    }
    std::fs::remove_dir_all(&dir).expect("remove scratch dir");
}
