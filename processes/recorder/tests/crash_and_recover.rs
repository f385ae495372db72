//! Crash safety: a recorder killed with SIGKILL loses at most its open chunk, SIGTERM finishes
//! the file, and `rec recover` rewrites truncated or index-less files into valid ones while
//! saying what was lost.
//!
//! The killed recorder is a real process: this test binary re-runs itself as the child
//! (`recorder_child`, ignored unless the parent sets its environment).

mod common;

use common::*;
use harvest_ipc::payloads::ArmState;
use harvest_ipc::{Context, Domain, Payload};
use harvest_recording::rec_cat::{CatOptions, cat};
use harvest_recording::rec_info::info;
use harvest_recording::recover::{RecoverError, recover};
use harvest_recording::scan::{ScanEnd, ScanItem, ScanOptions, scan_file};
use std::io::{BufRead, BufReader};
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

const CHILD_DIR_ENV: &str = "HARVEST_RECORDER_TEST_CHILD_DIR";
const CHILD_DOMAIN_ENV: &str = "HARVEST_RECORDER_TEST_CHILD_DOMAIN";

/// The recorder process of the kill tests (does nothing unless run by them).
#[test]
#[ignore = "child process of the crash tests"]
fn recorder_child() {
    let (Ok(dir), Ok(domain)) = (
        std::env::var(CHILD_DIR_ENV),
        std::env::var(CHILD_DOMAIN_ENV),
    ) else {
        return;
    };
    let domain = Domain::new(&domain).expect("domain");
    let mut args = test_args(Path::new(&dir));
    args.include = vec!["arm1/state".into()];
    args.chunk_interval = Duration::from_millis(50);
    let control = Arc::new(harvest_recorder::RecorderControl::new(
        Duration::from_millis(20),
    ));
    let watcher_control = control.clone();
    std::thread::spawn(move || {
        while !watcher_control.ready.load(Ordering::SeqCst) {
            std::thread::sleep(Duration::from_millis(5));
        }
        println!("READY");
    });
    let report = harvest_recorder::run_recorder_until(&args, &domain, "recorder-child", &control)
        .expect("recorder");
    println!("ENDED {:?}", report.end);
}

/// Starts the child recorder and waits for its READY line.
fn spawn_child(domain: &Domain, dir: &Path) -> Child {
    let mut child = Command::new(std::env::current_exe().expect("test binary"))
        .args([
            "--ignored",
            "--exact",
            "recorder_child",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_DIR_ENV, dir)
        .env(CHILD_DOMAIN_ENV, domain.name())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn child recorder");
    let stdout = child.stdout.take().expect("stdout");
    let (ready_sender, ready) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if line.trim_end().ends_with("READY") {
                let _ = ready_sender.send(());
            }
        }
    });
    if ready.recv_timeout(Duration::from_secs(30)).is_err() {
        let _ = child.kill();
        panic!("child recorder never became ready");
    }
    child
}

fn signal(child: &Child, signal: nix::sys::signal::Signal) {
    nix::sys::signal::kill(nix::unistd::Pid::from_raw(child.id() as i32), signal)
        .expect("signal child");
}

/// Arm-state sequence numbers found in a file by the scanner (valid part only).
fn recorded_sequences(path: &Path) -> Vec<u32> {
    let mut sequences = Vec::new();
    let _ = scan_file(path, ScanOptions::default(), |item| {
        if let ScanItem::Message(message) = item
            && message.channel.topic == "arm1/state"
        {
            sequences.push(message.sequence);
        }
        ControlFlow::Continue(())
    });
    sequences
}

fn publish_arm_states(
    publisher: &mut harvest_ipc::Publisher<ArmState>,
    range: std::ops::Range<u32>,
) {
    for index in range {
        publisher.publish(&arm_state(index)).expect("publish");
    }
}

#[test]
fn sigkill_loses_at_most_the_open_chunk_and_recover_keeps_the_rest() {
    let domain = unique_domain("kill");
    let dir = TempDir::new("kill");
    let mut child = spawn_child(&domain, dir.path());
    let context = Context::new(&domain, "publisher").expect("node");
    let mut arm = context
        .publisher(harvest_ipc::catalogue::ARM_STATE[0])
        .expect("publisher");
    publish_arm_states(&mut arm, 0..30);
    let file = mcap_files(dir.path()).pop().expect("the recorder's file");
    // Wait until the recorder has closed the chunks holding the first 30 messages.
    wait_until("30 messages in closed chunks", || {
        recorded_sequences(&file).len() >= 30
    });
    publish_arm_states(&mut arm, 30..40);
    signal(&child, nix::sys::signal::Signal::SIGKILL);
    let status = child.wait().expect("wait child");
    assert!(!status.success(), "killed");
    // What the killed node left in shared memory.
    harvest_ipc::cleanup::remove_dead_nodes(&domain).expect("cleanup");

    let summary = info(&file).expect("info on a killed recording");
    assert!(!summary.indexed);
    assert!(!summary.problems.is_empty());

    let out = dir.path().join("recovered.out.mcap");
    let report = recover(&file, &out, false).expect("recover");
    let recovered = report
        .messages_per_topic
        .get("arm1/state")
        .copied()
        .unwrap_or(0);
    assert!(
        (30..=40).contains(&recovered),
        "recovered {recovered} of 40\n{report}"
    );
    assert!(matches!(report.end, ScanEnd::Truncated { .. }), "{report}");
    assert!(!report.has_drop_counts);
    let read = python_read(&out);
    assert_eq!(read["has_summary"], true);
    let sequences: Vec<u64> = read["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .filter(|m| m["topic"] == "arm1/state")
        .map(|m| m["sequence"].as_u64().expect("sequence"))
        .collect();
    assert_eq!(
        sequences,
        (1..=recovered).collect::<Vec<_>>(),
        "a contiguous prefix survives"
    );
    for message in read["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .filter(|m| m["topic"] == "arm1/state")
    {
        let mut state = ArmState::default();
        ArmState::decode_into(
            &from_hex(message["data_hex"].as_str().expect("hex")),
            &mut state,
        )
        .expect("intact");
        assert_eq!(state.apple_id, 1000 + state.header.msg_seq as u32 - 1);
    }
    assert!(
        read["metadata"]
            .as_array()
            .expect("metadata")
            .iter()
            .any(|m| m["name"] == "harvest.recovery")
    );
}

#[test]
fn sigterm_ends_the_recording_cleanly() {
    let domain = unique_domain("term");
    let dir = TempDir::new("term");
    let mut child = spawn_child(&domain, dir.path());
    let context = Context::new(&domain, "publisher").expect("node");
    let mut arm = context
        .publisher(harvest_ipc::catalogue::ARM_STATE[0])
        .expect("publisher");
    publish_arm_states(&mut arm, 0..25);
    let file = mcap_files(dir.path()).pop().expect("the recorder's file");
    wait_until("25 messages written", || {
        recorded_sequences(&file).len() >= 25
    });
    signal(&child, nix::sys::signal::Signal::SIGTERM);
    let status = child.wait().expect("wait child");
    assert!(
        status.success(),
        "the recorder exits normally on SIGTERM: {status}"
    );
    let read = python_read(&file);
    assert_eq!(read["has_summary"], true);
    let count = read["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .filter(|m| m["topic"] == "arm1/state")
        .count();
    assert_eq!(count, 25);
    let drops = read["metadata"]
        .as_array()
        .expect("metadata")
        .iter()
        .find(|m| m["name"] == "harvest.drops")
        .expect("drops");
    assert_eq!(drops["metadata"]["arm1/state.received"], "25");
}

/// Records `count` arm states into small chunks (about three messages each).
fn small_chunk_recording(dir: &Path, count: u32) -> PathBuf {
    let domain = unique_domain("chunks");
    let mut args = test_args(dir);
    args.include = vec!["arm1/state".into()];
    // Chunks of the raw channel alone (counted below), without the mapped Foxglove channels.
    args.no_foxglove = true;
    args.chunk_size = 400;
    args.chunk_interval = Duration::from_secs(60);
    let recorder = RunningRecorder::start(&domain, args);
    recorder.wait_ready();
    let context = Context::new(&domain, "publisher").expect("node");
    let mut arm = context
        .publisher(harvest_ipc::catalogue::ARM_STATE[0])
        .expect("publisher");
    publish_arm_states(&mut arm, 0..count);
    let report = recorder.stop().expect("recording");
    assert_eq!(report.messages_written(), u64::from(count));
    report.files[0].clone()
}

/// (chunk offset, chunk record bytes, arm messages in the chunk) of every chunk.
fn chunk_layout(path: &Path) -> Vec<(u64, u64, u64)> {
    let mut chunks: Vec<(u64, u64, u64)> = Vec::new();
    scan_file(path, ScanOptions::default(), |item| {
        match item {
            ScanItem::Chunk(chunk) => chunks.push((chunk.offset, chunk.record_bytes, 0)),
            ScanItem::Message(message) if message.channel.topic == "arm1/state" => {
                if let Some(last) = chunks.last_mut() {
                    last.2 += 1;
                }
            }
            _ => {}
        }
        ControlFlow::Continue(())
    })
    .expect("scan");
    chunks
}

#[test]
fn recover_rewrites_a_file_cut_mid_chunk_or_without_index() {
    let dir = TempDir::new("cut");
    let original = small_chunk_recording(dir.path(), 60);
    let bytes = std::fs::read(&original).expect("read");
    let chunks: Vec<_> = chunk_layout(&original)
        .into_iter()
        .filter(|chunk| chunk.2 > 0)
        .collect();
    assert!(chunks.len() >= 10, "many small chunks: {}", chunks.len());
    let cut_chunk = chunks.len() / 2;
    let (cut_offset, cut_length, _) = chunks[cut_chunk];
    let kept: u64 = chunks[..cut_chunk].iter().map(|chunk| chunk.2).sum();

    // Cut in the middle of a chunk.
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..(cut_offset + cut_length / 2) as usize]).expect("write cut");
    let out = dir.path().join("cut-recovered.mcap");
    let report = recover(&cut, &out, false).expect("recover");
    assert_eq!(
        report.messages_per_topic.get("arm1/state").copied(),
        Some(kept),
        "{report}"
    );
    match &report.end {
        ScanEnd::Truncated { offset, reason } => {
            assert_eq!(*offset, cut_offset, "stops at the cut chunk");
            assert!(reason.contains(&cut_offset.to_string()), "{reason}");
        }
        other => panic!("expected a truncation, got {other:?}"),
    }
    assert_eq!(report.lost_tail_bytes(), cut_length / 2);
    assert!(report.to_string().contains("LOST"));
    let read = python_read(&out);
    assert_eq!(read["has_summary"], true);
    assert_eq!(
        read["messages"].as_array().expect("messages").len() as u64,
        kept
    );
    let fixed = info(&out).expect("info");
    assert!(fixed.indexed && fixed.problems.is_empty(), "{fixed}");

    // A time window on the cut (summary-less) file: the chunks before the window deliver no
    // messages but still define the channels.
    let mut times = Vec::new();
    scan_file(&cut, ScanOptions::default(), |item| {
        if let ScanItem::Message(message) = item {
            times.push(message.log_time);
        }
        ControlFlow::Continue(())
    })
    .expect("scan");
    let skip = chunks[0].2 + chunks[1].2;
    let start = Duration::from_nanos(times[skip as usize] - times[0]);
    let mut lines = Vec::new();
    let options = CatOptions {
        start: Some(start),
        ..CatOptions::default()
    };
    let report = cat(&cut, &options, &mut lines).expect("cat");
    assert_eq!(report.printed, kept - skip);
    assert!(report.incomplete.is_some());

    // Cut exactly at a chunk boundary: no partial record, but no index either.
    let indexless = dir.path().join("indexless.mcap");
    std::fs::write(&indexless, &bytes[..cut_offset as usize]).expect("write");
    let out = dir.path().join("indexless-recovered.mcap");
    let report = recover(&indexless, &out, false).expect("recover");
    assert_eq!(
        report.messages_per_topic.get("arm1/state").copied(),
        Some(kept)
    );
    assert_eq!(report.lost_tail_bytes(), 0);
    assert!(
        matches!(&report.end, ScanEnd::Truncated { reason, .. } if reason.contains("data-end"))
    );

    // A complete file: nothing lost, every message and metadata record kept.
    let out = dir.path().join("complete-recovered.mcap");
    let report = recover(&original, &out, false).expect("recover");
    assert!(report.nothing_lost(), "{report}");
    assert_eq!(report.messages(), 60);
    assert!(report.has_drop_counts);

    // Refusals: existing output, output = input.
    assert!(matches!(
        recover(&original, &out, false),
        Err(RecoverError::OutputExists(_))
    ));
    assert!(matches!(
        recover(&original, &original, true),
        Err(RecoverError::SameFile(_))
    ));
}
