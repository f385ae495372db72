//! Bad input never panics: non-MCAP files, truncation anywhere, corrupted bytes, unknown
//! schemas, recordings of another payload version, a full disk. Errors are clear and whatever
//! is valid is still read.

mod common;

use common::*;
use harvest_ipc::Context;
use harvest_ipc::catalogue::{ARM_STATE, VACUUM_STATE};
use harvest_rec::replay::{ReplayArgs, ReplayError, run_replay_with};
use harvest_recording::export::{ExportError, ExportOptions, export};
use harvest_recording::rec_cat::{CatError, CatOptions, cat};
use harvest_recording::rec_info::{InfoError, info};
use harvest_recording::recording_file::ReadError;
use harvest_recording::recover::{RecoverError, recover};
use harvest_recording::scan::{ScanEnd, ScanOptions, scan_file};
use harvest_recording::schema::catalogue_topics;
use harvest_recording::segment_writer::{ChunkCompression, ChunkSettings, SegmentWriter};
use std::collections::BTreeMap;
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

fn small_recording(dir: &Path) -> PathBuf {
    let domain = unique_domain("bad");
    let mut args = test_args(dir);
    args.include = vec!["arm1/state".into(), "vacuum/state".into()];
    args.chunk_size = 400;
    args.chunk_interval = Duration::from_secs(60);
    // The raw channels alone: the mapped Foxglove messages arrive at their own times, so the
    // chunks (and the message counts the tests compare) would depend on the machine's load.
    args.no_foxglove = true;
    let recorder = RunningRecorder::start(&domain, args);
    recorder.wait_ready();
    let context = Context::new(&domain, "publisher").expect("node");
    let mut arm = context.publisher(ARM_STATE[0]).expect("publisher");
    let mut vacuum = context.publisher(VACUUM_STATE).expect("publisher");
    for index in 0..30 {
        arm.publish(&arm_state(index)).expect("publish");
        vacuum.publish(&vacuum_state(index)).expect("publish");
    }
    recorder.stop().expect("recording").files[0].clone()
}

#[test]
fn files_that_are_not_recordings_are_refused_by_every_tool() {
    let dir = TempDir::new("notmcap");
    let text = dir.path().join("notes.mcap");
    std::fs::write(&text, "this is a text file, not a recording\n").expect("write");
    let empty = dir.path().join("empty.mcap");
    std::fs::write(&empty, "").expect("write");
    let missing = dir.path().join("missing.mcap");
    for path in [&text, &empty] {
        let error = info(path).expect_err("info");
        assert!(
            matches!(error, InfoError::Read(ReadError::NotMcap { .. })),
            "{error}"
        );
        assert!(
            error.to_string().contains(&path.display().to_string()),
            "{error}"
        );
        let error = cat(path, &CatOptions::default(), &mut Vec::new()).expect_err("cat");
        assert!(
            matches!(error, CatError::Read(ReadError::NotMcap { .. })),
            "{error}"
        );
        let error = recover(path, &dir.path().join("out.mcap"), true).expect_err("recover");
        assert!(
            matches!(error, RecoverError::Read(ReadError::NotMcap { .. })),
            "{error}"
        );
        assert!(
            !dir.path().join("out.mcap").exists(),
            "no output for a refused input"
        );
        let options = ExportOptions {
            png_dir: Some(dir.path().join("png")),
            ..ExportOptions::default()
        };
        assert!(matches!(
            export(path, &options),
            Err(ExportError::Read(ReadError::NotMcap { .. }))
        ));
        let args = ReplayArgs::for_files(vec![path.clone()]);
        let error = run_replay_with(&args, &unique_domain("badrep"), |_| {}).expect_err("replay");
        assert!(
            matches!(error, ReplayError::Read(ReadError::NotMcap { .. })),
            "{error}"
        );
    }
    assert!(matches!(
        info(&missing),
        Err(InfoError::Read(ReadError::Open { .. }))
    ));
    assert!(info(dir.path()).is_err(), "a directory is refused");

    // Only the magic: a valid start and nothing else.
    let magic = dir.path().join("magic.mcap");
    std::fs::write(&magic, mcap::MAGIC).expect("write");
    let summary = info(&magic).expect("info");
    assert_eq!(summary.messages, 0);
    assert!(!summary.problems.is_empty());
}

#[test]
fn truncation_and_corruption_anywhere_never_panic_and_keep_the_valid_part() {
    let dir = TempDir::new("fuzz");
    let original = small_recording(dir.path());
    let bytes = std::fs::read(&original).expect("read");
    let mutated = dir.path().join("mutated.mcap");
    let out = dir.path().join("out.mcap");
    let exercise = |data: &[u8]| {
        std::fs::write(&mutated, data).expect("write");
        if let Ok(outcome) = scan_file(&mutated, ScanOptions::default(), |_| {
            std::ops::ControlFlow::Continue(())
        }) {
            assert!(outcome.valid_bytes <= data.len() as u64);
        }
        let _ = info(&mutated).map(|summary| summary.to_string());
        let _ = cat(
            &mutated,
            &CatOptions {
                start: Some(Duration::from_millis(1)),
                ..CatOptions::default()
            },
            &mut Vec::new(),
        );
        if let Ok(report) = recover(&mutated, &out, true) {
            let _ = report.to_string();
            info(&out).expect("a recovered file is always readable");
        }
    };
    // Cut at many places.
    for cut in (0..bytes.len()).step_by(41) {
        exercise(&bytes[..cut]);
    }
    // Flip bytes at pseudo-random places.
    let mut state = 0x2545_f491u32;
    for _ in 0..150 {
        let mut data = bytes.clone();
        for _ in 0..3 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let position = state as usize % data.len();
            data[position] ^= 1 << (state >> 29);
        }
        exercise(&data);
    }
    // Garbage after a valid magic.
    let mut garbage = mcap::MAGIC.to_vec();
    garbage.extend((0..20_000u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8));
    exercise(&garbage);
}

#[test]
fn a_damaged_chunk_is_skipped_and_the_others_are_read() {
    let dir = TempDir::new("damaged");
    let original = small_recording(dir.path());
    let mut bytes = std::fs::read(&original).expect("read");
    let mut chunks = Vec::new();
    let mut total = 0u64;
    scan_file(&original, ScanOptions::default(), |item| {
        match item {
            harvest_recording::scan::ScanItem::Chunk(chunk) => {
                chunks.push((chunk.offset, chunk.record_bytes, 0u64))
            }
            harvest_recording::scan::ScanItem::Message(_) => {
                total += 1;
                if let Some(last) = chunks.last_mut() {
                    last.2 += 1;
                }
            }
            _ => {}
        }
        std::ops::ControlFlow::Continue(())
    })
    .expect("scan");
    let (offset, length, lost) = chunks[chunks.len() / 2];
    assert!(lost > 0);
    // Damage the end of the chunk's compressed data.
    for position in (offset + length - 8)..(offset + length - 2) {
        bytes[position as usize] ^= 0x5a;
    }
    let damaged = dir.path().join("damaged.mcap");
    std::fs::write(&damaged, &bytes).expect("write");
    let outcome = scan_file(&damaged, ScanOptions::default(), |_| {
        std::ops::ControlFlow::Continue(())
    })
    .expect("scan");
    assert_eq!(outcome.damaged_chunks.len(), 1, "{outcome:?}");
    assert_eq!(outcome.damaged_chunks[0].offset, offset);
    assert_eq!(
        outcome.end,
        ScanEnd::Complete,
        "reading goes on after the damaged chunk"
    );
    assert_eq!(outcome.messages, total - lost);
    let report = recover(&damaged, &dir.path().join("fixed.mcap"), false).expect("recover");
    assert_eq!(report.messages(), total - lost);
    assert!(report.to_string().contains("damaged chunk"), "{report}");
}

/// Writes a file with channels this build cannot decode next to one it can.
fn foreign_recording(path: &Path) {
    let mut writer = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).expect("create"),
    ))
    .expect("writer");
    writer
        .write_metadata(&mcap::records::Metadata {
            name: "harvest.recording".into(),
            metadata: BTreeMap::from([("software_version".to_owned(), "0.0.1".to_owned())]),
        })
        .expect("metadata");
    let old = writer
        .add_schema("harvest.ArmState.v0", "bincode2-fixint-le", b"old layout")
        .expect("schema");
    let old_channel = writer
        .add_channel(old, "arm1/state", "bincode2-fixint-le", &BTreeMap::new())
        .expect("channel");
    let alien = writer
        .add_schema("other.Thing", "jsonschema", b"{}")
        .expect("schema");
    let alien_channel = writer
        .add_channel(alien, "other/thing", "json", &BTreeMap::new())
        .expect("channel");
    let vacuum_topic = catalogue_topics()
        .into_iter()
        .find(|t| t.spec.topic == "vacuum/state")
        .expect("topic");
    let good = writer
        .add_schema(
            &vacuum_topic.schema_name(),
            "bincode2-fixint-le",
            vacuum_topic.schema_data().as_bytes(),
        )
        .expect("schema");
    let good_channel = writer
        .add_channel(good, "vacuum/state", "bincode2-fixint-le", &BTreeMap::new())
        .expect("channel");
    for (time, channel, data) in [
        (10, old_channel, vec![1u8, 2, 3]),
        (20, alien_channel, b"{\"a\":1}".to_vec()),
        (30, good_channel, encoded(&vacuum_state(4))),
        (40, good_channel, vec![9u8; 3]),
    ] {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: 1,
            log_time: time,
            publish_time: time,
        };
        writer
            .write_to_known_channel(&header, &data)
            .expect("message");
    }
    writer.finish().expect("finish");
}

#[test]
fn unknown_schemas_and_other_versions_are_reported_and_skipped() {
    let dir = TempDir::new("foreign");
    let file = dir.path().join("foreign.mcap");
    foreign_recording(&file);
    let summary = info(&file).expect("info");
    assert_eq!(summary.channels.len(), 3);
    assert_eq!(summary.software_version(), Some("0.0.1"));
    assert!(summary.to_string().contains("differs from this build"));

    let mut out = Vec::new();
    let report = cat(&file, &CatOptions::default(), &mut out).expect("cat");
    assert_eq!(report.printed, 1, "only the decodable vacuum message");
    let line: serde_json::Value =
        serde_json::from_slice(out.split(|&b| b == b'\n').next().expect("line")).expect("json");
    assert_eq!(line["topic"], "vacuum/state");
    let (count, reason) = &report.undecodable["arm1/state"];
    assert_eq!(*count, 1);
    assert!(reason.contains("v0") && reason.contains("v2"), "{reason}");
    assert!(
        report.undecodable["other/thing"]
            .1
            .contains("not a payload type")
    );
    assert!(
        report.undecodable["vacuum/state"].1.contains("undecodable"),
        "the 3-byte vacuum message"
    );

    let target = unique_domain("forrep");
    let args = ReplayArgs {
        fast: true,
        ..ReplayArgs::for_files(vec![file.clone()])
    };
    let report = run_replay_with(&args, &target, |_| {}).expect("replay");
    assert_eq!(report.published.get("vacuum/state"), Some(&1));
    assert_eq!(report.skipped["arm1/state"].0, 1);
    assert!(
        report.skipped["arm1/state"]
            .1
            .contains("harvest.ArmState.v2")
    );
    assert!(report.skipped.contains_key("other/thing"));
}

/// A disk that fills up after `capacity` bytes.
struct SmallDisk {
    data: Vec<u8>,
    position: usize,
    capacity: usize,
}

impl Write for SmallDisk {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let room = self.capacity.saturating_sub(self.position);
        if room == 0 {
            return Err(std::io::Error::from(std::io::ErrorKind::StorageFull));
        }
        let count = room.min(buf.len());
        let end = self.position + count;
        if self.data.len() < end {
            self.data.resize(end, 0);
        }
        self.data[self.position..end].copy_from_slice(&buf[..count]);
        self.position = end;
        Ok(count)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for SmallDisk {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.position = match to {
            SeekFrom::Start(offset) => offset as usize,
            SeekFrom::End(delta) => (self.data.len() as i64 + delta) as usize,
            SeekFrom::Current(delta) => (self.position as i64 + delta) as usize,
        };
        Ok(self.position as u64)
    }
}

#[test]
fn a_full_disk_is_a_clear_error_and_the_written_part_is_recoverable() {
    let topics = catalogue_topics();
    let camera = topics
        .iter()
        .position(|t| t.spec.topic == "camera/rgbd")
        .expect("camera");
    let settings = ChunkSettings {
        compression: ChunkCompression::Lz4,
        compression_level: 0,
        compression_threads: 0,
        chunk_size_bytes: 1 << 20,
    };
    let disk = SmallDisk {
        data: Vec::new(),
        position: 0,
        capacity: 24 << 20,
    };
    let mut writer = SegmentWriter::new(disk, &settings, topics.len()).expect("writer");
    let mut frame =
        harvest_recording::payload_codec::zeroed_box::<harvest_ipc::payloads::RgbdFrame>();
    let mut written = 0u64;
    let error = loop {
        fill_frame(&mut frame, written as u32);
        frame.header.msg_seq = written + 1;
        let bytes = encoded(&*frame);
        match writer.write_message(
            camera,
            &topics[camera],
            written as u32 + 1,
            written,
            written,
            &bytes,
        ) {
            Ok(()) => written += 1,
            Err(error) => break error,
        }
        assert!(written < 100, "the disk must fill up");
    };
    let text = harvest_recording::mcap_error::mcap_error_text(&error);
    assert!(text.contains("disk is full"), "{text}");
    // What reached the disk: take it out without finishing (the disk is full).
    let dir = TempDir::new("full");
    let partial = dir.path().join("partial.mcap");
    let SmallDisk { data, .. } = take_disk(writer);
    std::fs::write(&partial, &data).expect("write");
    let report = recover(&partial, &dir.path().join("recovered.mcap"), false).expect("recover");
    let recovered = report.messages();
    assert!(
        recovered >= 1 && recovered <= written,
        "recovered {recovered} of {written}\n{report}"
    );
}

fn take_disk(writer: SegmentWriter<SmallDisk>) -> SmallDisk {
    writer.into_stream()
}

#[test]
fn an_unusable_output_directory_is_a_clear_error() {
    let dir = TempDir::new("nodir");
    let blocker = dir.path().join("a-file");
    std::fs::write(&blocker, "not a directory").expect("write");
    let args = harvest_recorder::RecorderArgs {
        output_dir: blocker.join("recordings"),
        ..test_args(dir.path())
    };
    let control = harvest_recorder::RecorderControl::new(Duration::from_millis(20));
    let error =
        harvest_recorder::run_recorder_until(&args, &unique_domain("nodir"), "recorder", &control)
            .expect_err("cannot record into a path under a file");
    assert!(error.to_string().contains("a-file/recordings"), "{error}");
}
