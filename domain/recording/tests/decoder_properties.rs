//! Property tests of every reader of recording files: a small valid
//! recording written with the segment writer, then truncated, mutated, given CRC-valid but
//! malformed chunks or garbage, goes through the scanner, the summary readers, `rec info`,
//! `rec cat`, `rec export` and `rec recover`. None may panic; whatever they report must be
//! consistent with the bytes (a scan never claims more valid bytes than the file has, a
//! recovered file is always complete and holds what the scan of its input delivered).
//!
//! Case counts are bounded (see `CASES`) so the whole file runs in a few seconds on CI.

use harvest_ipc::Payload;
use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, PERCEPTION_APPLES, VACUUM_STATE,
};
use harvest_ipc::payloads::{AppleDetections, ArmCommand, ArmState, EmergencyStop, VacuumState};
use harvest_recording::export::{ExportOptions, export};
use harvest_recording::metadata;
use harvest_recording::payload_codec::{SchemaMatch, json_decoder};
use harvest_recording::rec_cat::{CatOptions, cat};
use harvest_recording::rec_info::info;
use harvest_recording::recording_file::{read_indexed_metadata, read_summary};
use harvest_recording::recover::recover;
use harvest_recording::scan::{ScanItem, ScanOptions, scan_file};
use harvest_recording::schema::{TopicInfo, catalogue_topics};
use harvest_recording::segment_writer::{ChunkCompression, ChunkSettings, SegmentWriter};
use harvest_recording::wall_clock::ClockPair;
use proptest::prelude::*;
use std::io::Cursor;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Cases per property: each case writes a few small files and runs five readers over them.
const CASES: u32 = 48;

/// A directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(label: &str) -> Self {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let path = std::env::temp_dir().join(format!(
            "harvest-recording-prop-{label}-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&path).expect("temp dir");
        Self(path)
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A payload of type `T` whose bytes are `bytes` repeated (any bit pattern is a valid payload
/// by the `Payload` contract), written through raw bytes so it keeps working whatever the
/// field types become.
fn payload_from_bytes<T: Payload>(bytes: &[u8]) -> Box<T> {
    let mut value = harvest_ipc::payload::boxed_zeroed::<T>();
    if !bytes.is_empty() {
        // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every
        // bit pattern is a valid `T` (the `Payload` contract).
        let raw = unsafe {
            std::slice::from_raw_parts_mut(
                (&mut *value as *mut T).cast::<u8>(),
                std::mem::size_of::<T>(),
            )
        };
        for (byte, source) in raw.iter_mut().zip(bytes.iter().cycle()) {
            *byte = *source;
        }
    }
    value
}

fn encoded<T: Payload>(value: &T) -> Vec<u8> {
    let mut out = Vec::new();
    value.encode(&mut out).expect("encode");
    out
}

/// The channels of the test recording: the monitored ones and the detections.
fn topics() -> Vec<TopicInfo> {
    vec![
        TopicInfo::of(VACUUM_STATE),
        TopicInfo::of(ARM_STATE[0]),
        TopicInfo::of(ARM_COMMAND[0]),
        TopicInfo::of(EMERGENCY_STOP),
        TopicInfo::of(PERCEPTION_APPLES),
    ]
}

/// The encoded message of topic `index` number `n`: well-formed payloads, or (when `wild` is
/// given) payloads made of those bytes.
fn message(index: usize, n: u64, wild: Option<&[u8]>) -> Vec<u8> {
    fn make<T: Payload + Default>(n: u64, wild: Option<&[u8]>) -> Vec<u8> {
        match wild {
            Some(bytes) => encoded(&*payload_from_bytes::<T>(bytes)),
            None => {
                let mut value = T::default();
                value.header_mut().msg_seq = n;
                value.header_mut().capture_ns = 1_000_000_000 + n * 5_000_000;
                encoded(&value)
            }
        }
    }
    match index {
        0 => make::<VacuumState>(n, wild),
        1 => make::<ArmState>(n, wild),
        2 => make::<ArmCommand>(n, wild),
        3 => make::<EmergencyStop>(n, wild),
        _ => make::<AppleDetections>(n, wild),
    }
}

/// A finished recording of `count` messages per topic, chunks of about `chunk_bytes`, with the
/// metadata records a recorder writes; `wild` payload bytes replace every third message.
fn recording(
    compression: ChunkCompression,
    chunk_bytes: u64,
    count: u64,
    wild: Option<&[u8]>,
) -> Vec<u8> {
    let settings = ChunkSettings {
        compression,
        compression_level: 1,
        compression_threads: 0,
        chunk_size_bytes: chunk_bytes,
    };
    let topics = topics();
    let mut writer =
        SegmentWriter::new(Cursor::new(Vec::new()), &settings, topics.len()).expect("writer");
    writer
        .write_metadata(&metadata::record(
            metadata::RECORDING,
            [("software_version", metadata::SOFTWARE_VERSION)],
        ))
        .expect("metadata");
    writer
        .write_metadata(&metadata::clock_record(
            ClockPair {
                monotonic_ns: 1_000_000_000,
                realtime_ns: 1_700_000_000_000_000_000,
            },
            None,
        ))
        .expect("metadata");
    for n in 0..count {
        for (index, topic) in topics.iter().enumerate() {
            let data = message(index, n, wild.filter(|_| n % 3 == 2));
            let log_time_ns = 1_000_000_000 + n * 5_000_000 + index as u64;
            writer
                .write_message(index, topic, n as u32, log_time_ns, log_time_ns, &data)
                .expect("message");
        }
    }
    writer
        .write_metadata(&metadata::notes_record(&["operator=prop".to_owned()]))
        .expect("metadata");
    writer.finish().expect("finish").into_inner()
}

fn compression() -> impl Strategy<Value = ChunkCompression> {
    prop_oneof![
        Just(ChunkCompression::Zstd),
        Just(ChunkCompression::Lz4),
        Just(ChunkCompression::None),
    ]
}

/// Runs every reader over `data` (written to `dir/input.mcap`) and checks what they report.
fn every_reader(dir: &Path, data: &[u8]) -> Result<(), TestCaseError> {
    let input = dir.join("input.mcap");
    std::fs::write(&input, data).expect("write input");

    // The scanner, whole file and through a time window.
    let mut delivered = 0u64;
    let scanned = scan_file(&input, ScanOptions::default(), |item| {
        if let ScanItem::Message(message) = item {
            delivered += 1;
            let _ = message.data.len();
        }
        ControlFlow::Continue(())
    });
    if let Ok(outcome) = &scanned {
        prop_assert!(outcome.valid_bytes <= data.len() as u64, "{outcome:?}");
        prop_assert_eq!(outcome.file_bytes, data.len() as u64);
        prop_assert_eq!(outcome.messages, delivered);
    }
    let _ = scan_file(
        &input,
        ScanOptions {
            log_time_window: Some((1_010_000_000, 1_030_000_000)),
        },
        |_| ControlFlow::Continue(()),
    );

    // The summary and the metadata it indexes.
    if let Ok(Some(summary)) = read_summary(&input) {
        let _ = read_indexed_metadata(&input, &summary.metadata_indexes);
    }

    // rec info.
    if let Ok(summary) = info(&input) {
        let _ = summary.to_string();
        let _ = summary.duration_s();
        let _ = summary.software_version();
    }

    // rec cat, with and without a window.
    let mut out = Vec::new();
    let _ = cat(&input, &CatOptions::default(), &mut out);
    let _ = cat(
        &input,
        &CatOptions {
            topics: vec!["arm*".to_owned()],
            start: Some(Duration::from_millis(3)),
            end: Some(Duration::from_millis(40)),
        },
        &mut Vec::new(),
    );

    // rec export (Foxglove and PNG).
    let _ = export(
        &input,
        &ExportOptions {
            png_dir: Some(dir.join("png")),
            foxglove: Some(dir.join("foxglove.mcap")),
            ..ExportOptions::default()
        },
    );

    // rec recover: the output is always complete and holds every message the scan delivered.
    let output = dir.join("recovered.mcap");
    if let Ok(report) = recover(&input, &output, true) {
        let _ = report.to_string();
        let again = scan_file(&output, ScanOptions::default(), |_| {
            ControlFlow::Continue(())
        })
        .expect("a recovered file is readable");
        prop_assert!(again.is_intact(), "recovered file damaged: {again:?}");
        if let Ok(outcome) = &scanned {
            prop_assert_eq!(again.messages, outcome.messages);
        }
        info(&output).expect("a recovered file has readable info");
    }
    Ok(())
}

/// The offset, length and records region of every chunk of an uncompressed recording.
fn chunk_regions(path: &Path) -> Vec<(usize, usize)> {
    let mut chunks = Vec::new();
    scan_file(path, ScanOptions::default(), |item| {
        if let ScanItem::Chunk(chunk) = item {
            chunks.push((chunk.offset as usize, chunk.record_bytes as usize));
        }
        ControlFlow::Continue(())
    })
    .expect("scan");
    chunks
}

/// Recomputes the CRC of the uncompressed chunk record at `offset` (layout: opcode, u64 length,
/// start u64, end u64, uncompressed size u64, CRC u32, compression string, records u64 + bytes).
/// Returns the range of its records.
fn records_of_uncompressed_chunk(bytes: &[u8], offset: usize) -> Option<(usize, usize, usize)> {
    let body = offset + 9;
    let crc_at = body + 24;
    let compression_len =
        u32::from_le_bytes(bytes.get(crc_at + 4..crc_at + 8)?.try_into().ok()?) as usize;
    let records_len_at = crc_at + 8 + compression_len;
    let records_len = u64::from_le_bytes(
        bytes
            .get(records_len_at..records_len_at + 8)?
            .try_into()
            .ok()?,
    ) as usize;
    let start = records_len_at + 8;
    (start + records_len <= bytes.len()).then_some((crc_at, start, start + records_len))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// A recording cut anywhere (a recorder killed mid-write) is read up to the cut.
    #[test]
    fn truncated_recordings_are_read_up_to_the_cut(
        compression in compression(),
        chunk_bytes in 64u64..2048,
        cut_fraction in 0.0f64..1.0,
    ) {
        let dir = TempDir::new("cut");
        let bytes = recording(compression, chunk_bytes, 12, None);
        let cut = (bytes.len() as f64 * cut_fraction) as usize;
        every_reader(dir.path(), &bytes[..cut])?;
    }

    /// Bytes overwritten anywhere (bad sectors, a corrupted copy): no reader panics.
    #[test]
    fn mutated_recordings_never_panic(
        compression in compression(),
        chunk_bytes in 64u64..2048,
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..12),
    ) {
        let dir = TempDir::new("mutate");
        let mut bytes = recording(compression, chunk_bytes, 12, None);
        for (index, value) in &edits {
            let at = index.index(bytes.len());
            bytes[at] = *value;
        }
        every_reader(dir.path(), &bytes)?;
    }

    /// Chunks whose CRC is right but whose records are malformed (a buggy writer): the inner
    /// record parser and the payload decoders see the damage, not the CRC check.
    #[test]
    fn crc_valid_malformed_chunks_never_panic(
        chunk_bytes in 64u64..1024,
        edits in prop::collection::vec((any::<prop::sample::Index>(), any::<prop::sample::Index>(), any::<u8>()), 1..8),
    ) {
        let dir = TempDir::new("chunk");
        let original = dir.path().join("original.mcap");
        let mut bytes = recording(ChunkCompression::None, chunk_bytes, 12, None);
        std::fs::write(&original, &bytes).expect("write");
        let chunks = chunk_regions(&original);
        prop_assume!(!chunks.is_empty());
        for (chunk, position, value) in &edits {
            let (offset, _) = chunks[chunk.index(chunks.len())];
            let Some((crc_at, start, end)) = records_of_uncompressed_chunk(&bytes, offset) else {
                continue;
            };
            if end > start {
                bytes[start + position.index(end - start)] = *value;
            }
            let crc = crc32fast::hash(&bytes[start..end]);
            bytes[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
        }
        every_reader(dir.path(), &bytes)?;
    }

    /// Payloads of any bit pattern (NaN, infinities, unknown codes, lengths past their arrays,
    /// strings that are not UTF-8) recorded as valid messages: cat and export decode or skip
    /// them.
    #[test]
    fn recorded_payloads_of_any_bit_pattern_never_panic(
        compression in compression(),
        wild in prop::collection::vec(any::<u8>(), 1..256),
    ) {
        let dir = TempDir::new("wild");
        let bytes = recording(compression, 512, 9, Some(&wild));
        every_reader(dir.path(), &bytes)?;
    }

    /// Anything after a valid magic.
    #[test]
    fn garbage_after_the_magic_never_panics(
        tail in prop::collection::vec(any::<u8>(), 0..4096),
    ) {
        let dir = TempDir::new("garbage");
        let mut bytes = mcap::MAGIC.to_vec();
        bytes.extend_from_slice(&tail);
        every_reader(dir.path(), &bytes)?;
    }

    /// Every catalogue payload decoder, fed any bytes as a recorded message of its schema:
    /// an error or a value, and the JSON view of the value.
    #[test]
    fn every_payload_decoder_takes_any_bytes(
        topic in any::<prop::sample::Index>(),
        bytes in prop::collection::vec(any::<u8>(), 0..512),
    ) {
        let topics = catalogue_topics();
        let topic = topics[topic.index(topics.len())];
        let SchemaMatch::Known(mut decoder) = json_decoder(&topic.schema_name()) else {
            return Err(TestCaseError::fail(format!("{} has no decoder", topic.schema_name())));
        };
        if let Ok(value) = decoder.to_json(&bytes) {
            let _ = value.to_string();
        }
    }
}
