//! The field workflow end to end with the real processes over real shared memory:
//! `harvest up --launch processes/supervisor/launch/row.toml --until-row-done` works a two-stop
//! row in a private domain (the executive's stop cycle positions the platform, waits for fresh
//! detections, harvests, advances the tractor), prints one line per stop and a row summary,
//! and its counts match the simulator's ground truth; a `kill -9` of the sim process mid-row
//! (restarted by `harvest up`, its world restored from its state file) harvests no apple twice,
//! loses none, and the row completes.

mod common;

use common::*;
use harvest_ipc::catalogue::SIM_GROUND_TRUTH;
use harvest_ipc::payloads::TrueAppleState;
use harvest_ipc::{Context, Domain};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const ROW_LAUNCH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/processes/supervisor/launch/row.toml"
);

/// The number after `key ` in `line`.
fn count_after(line: &str, key: &str) -> Option<u32> {
    let start = line.find(&format!("{key} "))? + key.len() + 1;
    line[start..]
        .split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

#[test]
fn a_two_stop_row_completes_with_counts_matching_ground_truth_and_a_second_run_ends_it() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("row");
    let (stdout, truth) = run_row(&domain, None);
    check_row(&stdout, truth);

    // The same command again: the world kept its state (trailer at the last stop, harvested
    // apples off the tree), so the run works the one stop left and ends the row there instead
    // of waiting for a tractor that cannot drive past the row's end.
    let first_harvested = truth.expect("ground truth of the first run");
    let (again, truth_again) = run_row(&domain, None);
    let stop_lines: Vec<&str> = again
        .lines()
        .filter(|l| l.contains(" @") && l.contains("platform ("))
        .collect();
    assert_eq!(stop_lines.len(), 1, "{again}");
    assert!(stop_lines[0].contains("stop 1 @2.00 m"), "{again}");
    assert!(again.contains("row summary (1 stops)"), "{again}");
    // Nothing harvested twice, nothing lost: the simulator's count grew by this run's.
    let harvested_again = summary_count(&again, "harvested").expect("summary line") as usize;
    assert_eq!(
        truth_again,
        Some(first_harvested + harvested_again),
        "ground truth disagrees with the two runs:\n{again}"
    );
}

/// The sim is killed while a cup holds an apple (the hard case: the apple must stay on the cup
/// across the restart and be counted once, when released).
#[test]
fn a_kill_9_of_the_sim_mid_row_harvests_no_apple_twice_and_the_row_completes() {
    let _stack = one_stack_at_a_time();
    let domain = unique_domain("rowkill");
    let (stdout, truth) = run_row(&domain, Some(3));
    check_row(&stdout, truth);
}

/// The sim process among the supervisor's children.
fn sim_pid(supervisor: u32) -> Option<u32> {
    children_of(supervisor).into_iter().find(|pid| {
        std::fs::read(format!("/proc/{pid}/cmdline")).is_ok_and(|cmdline| {
            cmdline
                .split(|b| *b == 0)
                .nth(1)
                .is_some_and(|arg| arg == b"sim")
        })
    })
}

/// Runs the row; with `kill_after`, kills the sim with SIGKILL once the ground truth shows
/// that many apples harvested and an apple on a cup. Returns stdout and the last ground-truth
/// harvested count.
fn run_row(domain: &str, kill_after: Option<usize>) -> (String, Option<usize>) {
    let domain = domain.to_owned();

    // Ground truth, read while the stack runs: apples on the dropping module.
    let stop = Arc::new(AtomicBool::new(false));
    let truth_harvested = Arc::new(Mutex::new(None::<usize>));
    let apple_on_a_cup = Arc::new(AtomicBool::new(false));
    let truth_thread = {
        let (stop, truth_harvested, apple_on_a_cup, domain) = (
            stop.clone(),
            truth_harvested.clone(),
            apple_on_a_cup.clone(),
            domain.to_string(),
        );
        std::thread::spawn(move || {
            let domain = Domain::new(&domain).expect("domain");
            let context = Context::new(&domain, "test-truth").expect("context");
            let truth = context.subscriber(SIM_GROUND_TRUTH).expect("subscriber");
            while !stop.load(Ordering::SeqCst) {
                if let Ok(Some(sample)) = truth.receive_latest() {
                    let harvested = sample
                        .apples
                        .iter()
                        .filter(|a| a.state == TrueAppleState::Harvested)
                        .count();
                    let on_a_cup = sample.apples.iter().any(|a| {
                        a.state == TrueAppleState::OnArm1 || a.state == TrueAppleState::OnArm2
                    });
                    *truth_harvested.lock().expect("lock") = Some(harvested);
                    apple_on_a_cup.store(on_a_cup, Ordering::SeqCst);
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        })
    };

    let child = spawn_harvest(
        &domain,
        &[
            "up",
            "--launch",
            ROW_LAUNCH,
            "--until-row-done",
            "--duration",
            "400s",
        ],
    );
    let supervisor = child.id();
    let killed = Arc::new(AtomicU32::new(0));
    let killer = kill_after.map(|count| {
        let (stop, truth_harvested, apple_on_a_cup, killed) = (
            stop.clone(),
            truth_harvested.clone(),
            apple_on_a_cup.clone(),
            killed.clone(),
        );
        std::thread::spawn(move || {
            while !stop.load(Ordering::SeqCst) {
                let harvested = *truth_harvested.lock().expect("lock");
                if harvested.is_some_and(|h| h >= count)
                    && apple_on_a_cup.load(Ordering::SeqCst)
                    && let Some(pid) = sim_pid(supervisor)
                {
                    nix::sys::signal::kill(
                        nix::unistd::Pid::from_raw(pid as i32),
                        nix::sys::signal::Signal::SIGKILL,
                    )
                    .expect("kill -9 sim");
                    killed.store(pid, Ordering::SeqCst);
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        })
    });
    let (status, stdout, stderr) = wait_with_watchdog(child, Duration::from_secs(460));
    stop.store(true, Ordering::SeqCst);
    truth_thread.join().expect("truth thread");
    if let Some(killer) = killer {
        killer.join().expect("killer thread");
        assert_ne!(killed.load(Ordering::SeqCst), 0, "the sim was never killed");
        assert_eq!(summary_restarts(&stderr, "sim"), Some(1), "{stderr}");
    }

    assert!(status.success(), "harvest up failed:\n{stdout}\n{stderr}");
    assert!(
        stderr.contains("harvest up ended: row done"),
        "the row did not complete:\n{stdout}\n{stderr}"
    );
    let truth = *truth_harvested.lock().expect("lock");
    (stdout, truth)
}

/// The per-stop lines, the row line, the harvest summary and the ground truth agree.
fn check_row(stdout: &str, truth: Option<usize>) {
    // One line per stop, in order, then the row's line.
    let stops: Vec<&str> = stdout.lines().filter(|l| l.contains("stop ")).collect();
    let stop_lines: Vec<&str> = stops
        .iter()
        .copied()
        .filter(|l| l.contains(" @") && l.contains("platform ("))
        .collect();
    assert_eq!(stop_lines.len(), 2, "{stdout}");
    assert!(stop_lines[0].contains("stop 1 @0.00 m"), "{stdout}");
    assert!(stop_lines[1].contains("stop 2 @2.00 m"), "{stdout}");
    let row_line = stdout
        .lines()
        .find(|l| l.contains("row done: "))
        .expect("row line");
    let row_harvested = count_after(row_line, "harvested").expect("row harvested");
    let per_stop: u32 = stop_lines
        .iter()
        .map(|l| count_after(l, "ok").expect("ok count"))
        .sum();
    assert_eq!(per_stop, row_harvested, "{stdout}");
    // The harvest log's summary and the simulator agree with the row's count.
    let harvested = summary_count(stdout, "harvested").expect("summary line");
    assert!(harvested > 0, "nothing harvested:\n{stdout}");
    assert_eq!(harvested, row_harvested, "{stdout}");
    assert_eq!(
        truth,
        Some(harvested as usize),
        "ground truth disagrees with the summary:\n{stdout}"
    );
    // Out-of-reach apples are counted per stop, never silently dropped; each stop says how
    // many apples the laser refined and its failed attempts by cause.
    for line in &stop_lines {
        let detected = count_after(line, "of").expect("detected");
        let out = count_after(line, "out").expect("out of reach");
        assert!(out <= detected, "{line}");
        let laser = count_after(line, "laser").expect("laser refined");
        assert!(laser as usize <= detected as usize, "{line}");
        assert!(line.contains(", failed: "), "{line}");
        eprintln!("{line}");
    }
    assert!(stdout.contains("row summary (2 stops)"), "{stdout}");
}
