//! `harvest soak` on a short run against the real default stack (it starts `harvest up` in a
//! domain of its own): one scheduled SIGKILL, operator commands and bad inputs; the JSON report
//! has samples of every process, the killed process's restart is explained and no restart is
//! unexplained; the domain's files are gone afterwards. No timing is asserted.

mod common;

use common::*;
use serde_json::Value;
use std::time::Duration;

#[test]
fn a_short_soak_explains_its_one_kill() {
    let _stack = one_stack_at_a_time();
    let dir = TempDir::new("soak");
    let out = dir.0.join("soak.json");
    let domain = unique_domain("soakt");
    let (status, stdout, stderr) = run_harvest(
        &domain,
        &[
            "soak",
            "--duration",
            "40s",
            "--warmup",
            "12s",
            "--kill-every",
            "10s",
            "--max-kills",
            "1",
            "--ctl-every",
            "8s",
            "--bad-input-every",
            "5s",
            "--sample-every",
            "2s",
            "--out",
            out.to_str().expect("utf-8"),
        ],
        Duration::from_secs(240),
    );
    let report: Value = serde_json::from_str(
        &std::fs::read_to_string(&out)
            .unwrap_or_else(|e| panic!("no report ({e}); stdout:\n{stdout}\nstderr:\n{stderr}")),
    )
    .expect("JSON report");
    assert!(stdout.contains("verdicts:"), "{stdout}");

    let kills = report["kills"].as_array().expect("kills");
    let scheduled: Vec<&Value> = kills.iter().filter(|k| k["reason"] == "schedule").collect();
    assert_eq!(scheduled.len(), 1, "{kills:?}");
    let killed = scheduled[0]["process"].as_str().expect("name");
    assert!(
        scheduled[0]["pid"].is_u64(),
        "the process ran: {:?}",
        scheduled[0]
    );
    assert!(
        scheduled[0]["restarted_pid"].is_u64(),
        "{killed} restarted: {:?}\n{stdout}",
        scheduled[0]
    );
    let restarts = report["restarts"].as_array().expect("restarts");
    let of_killed = restarts
        .iter()
        .find(|r| r["process"] == killed)
        .expect("the killed process's restarts");
    assert!(of_killed["explained"].as_u64() >= Some(1), "{of_killed}");
    let unexplained: u64 = restarts
        .iter()
        .map(|r| r["unexplained"].as_u64().expect("count"))
        .sum();
    assert_eq!(unexplained, 0, "{restarts:?}\n{stdout}");

    let samples = report["samples"].as_array().expect("samples");
    assert!(samples.len() >= 5, "{} samples", samples.len());
    let last = &samples[samples.len() - 1]["processes"];
    for name in [
        "supervisor",
        "sim",
        "arm1",
        "arm2",
        "vacuum",
        "recorder",
        "monitor",
    ] {
        assert!(last[name]["rss_kib"].as_u64() > Some(0), "{name}: {last}");
        assert!(last[name]["fds"].as_u64() > Some(0), "{name}: {last}");
    }
    assert!(samples.iter().all(|s| s["shm_entries"].as_u64() > Some(0)));
    assert!(!report["ctl"].as_array().expect("ctl").is_empty());
    assert!(!report["bad_inputs"].as_array().expect("inputs").is_empty());
    assert_eq!(report["shm"]["left_after_stop"], 0, "{}", report["shm"]);
    assert!(
        report["stack_ended_early"].is_null(),
        "{}",
        report["stack_ended_early"]
    );
    assert!(
        status.success() || stdout.contains("FAIL"),
        "exit {status} without a failed verdict:\n{stdout}\n{stderr}"
    );
}
