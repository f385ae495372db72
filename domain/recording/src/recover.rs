//! `harvest rec recover IN OUT`: rewrites what is readable of a truncated, index-less or
//! partly damaged recording into a complete, indexed MCAP file, and says what was lost.
//!
//! Everything up to the last complete record is kept: schemas, channels, messages (same
//! stamps and sequence numbers) and metadata. Damaged chunks are skipped. The output gets a
//! `harvest.recovery` metadata record describing the repair.

use crate::mcap_error::mcap_error_text;
use crate::metadata;
use crate::recording_file::ReadError;
use crate::scan::{DamagedChunk, ScanEnd, ScanItem, ScanOptions, scan_file};
use crate::units::format_bytes;
use mcap::records::MessageHeader;
use mcap::{WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// What a recovery kept and lost.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecoverReport {
    pub input: PathBuf,
    pub output: PathBuf,
    pub input_bytes: u64,
    /// Bytes of the input read up to its last complete record.
    pub valid_bytes: u64,
    /// How the input ended.
    pub end: ScanEnd,
    pub damaged_chunks: Vec<DamagedChunk>,
    /// Recovered messages per topic.
    pub messages_per_topic: BTreeMap<String, u64>,
    pub first_log_time_ns: Option<u64>,
    pub last_log_time_ns: Option<u64>,
    pub metadata_records: u64,
    /// The recorder wrote its final drop counts (it ended cleanly).
    pub has_drop_counts: bool,
}

impl RecoverReport {
    pub fn messages(&self) -> u64 {
        self.messages_per_topic.values().sum()
    }

    /// Bytes at the end of the input that were lost.
    pub fn lost_tail_bytes(&self) -> u64 {
        match self.end {
            ScanEnd::Truncated { offset, .. } => self.input_bytes.saturating_sub(offset),
            _ => 0,
        }
    }

    /// True when nothing was lost.
    pub fn nothing_lost(&self) -> bool {
        self.end == ScanEnd::Complete && self.damaged_chunks.is_empty()
    }
}

impl std::fmt::Display for RecoverReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "recovered {} message(s) and {} metadata record(s) from {} into {}",
            self.messages(),
            self.metadata_records,
            self.input.display(),
            self.output.display()
        )?;
        if let (Some(first), Some(last)) = (self.first_log_time_ns, self.last_log_time_ns) {
            writeln!(
                f,
                "  time span kept: {:.3} s (log_time {first} .. {last} ns)",
                last.saturating_sub(first) as f64 * 1e-9
            )?;
        }
        for (topic, count) in &self.messages_per_topic {
            writeln!(f, "  {topic:<24} {count:>10}")?;
        }
        match &self.end {
            ScanEnd::Complete => writeln!(f, "  the input's data section was complete")?,
            ScanEnd::Truncated { offset, reason } => writeln!(
                f,
                "  LOST: the last {} of {} (from byte {offset}): {reason}. Messages written after \
the last recovered one (log_time {}) are gone.",
                format_bytes(self.lost_tail_bytes()),
                format_bytes(self.input_bytes),
                self.last_log_time_ns
                    .map(|t| t.to_string())
                    .unwrap_or_else(|| "-".to_owned())
            )?,
            ScanEnd::Stopped => {}
        }
        for damaged in &self.damaged_chunks {
            writeln!(
                f,
                "  LOST: damaged chunk at byte {} ({}, log_time {} .. {} ns): {}",
                damaged.offset,
                format_bytes(damaged.record_bytes),
                damaged.message_start_time,
                damaged.message_end_time,
                damaged.reason
            )?;
        }
        if !self.has_drop_counts {
            writeln!(
                f,
                "  note: the recorder did not end cleanly, so per-channel drop counts were never written"
            )?;
        }
        Ok(())
    }
}

/// Recovery failed.
#[derive(Debug, thiserror::Error)]
pub enum RecoverError {
    #[error(transparent)]
    Read(#[from] ReadError),
    /// The output path is the input.
    #[error("the output {0} is the input: choose another file")]
    SameFile(PathBuf),
    /// The output exists and `force` was not given.
    #[error("{0} exists: remove it or pass --force")]
    OutputExists(PathBuf),
    /// Writing the output failed.
    #[error("writing {path}: {reason}")]
    Write { path: PathBuf, reason: String },
}

/// True when `a` and `b` name the same existing file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// Rewrites the readable part of `input` into `output`.
pub fn recover(input: &Path, output: &Path, force: bool) -> Result<RecoverReport, RecoverError> {
    if same_file(input, output) {
        return Err(RecoverError::SameFile(output.to_path_buf()));
    }
    if output.exists() && !force {
        return Err(RecoverError::OutputExists(output.to_path_buf()));
    }
    // Check the input first so a non-MCAP input leaves no output behind.
    crate::recording_file::open_recording(input)?;
    let partial = output.with_extension("mcap.partial");
    let write_error = |reason: String| RecoverError::Write {
        path: output.to_path_buf(),
        reason,
    };
    let file = File::create(&partial).map_err(|error| write_error(error.to_string()))?;
    let options = WriteOptions::new()
        .profile("harvest")
        .compression(Some(mcap::Compression::Zstd))
        .compression_level(1)
        .compression_threads(0)
        .chunk_size(Some(4 << 20));
    let mut writer = Writer::with_options(BufWriter::with_capacity(1 << 20, file), options)
        .map_err(|error| write_error(mcap_error_text(&error)))?;
    let mut channel_ids: BTreeMap<u16, u16> = BTreeMap::new();
    let mut report = RecoverReport {
        input: input.to_path_buf(),
        output: output.to_path_buf(),
        input_bytes: 0,
        valid_bytes: 0,
        end: ScanEnd::Stopped,
        damaged_chunks: Vec::new(),
        messages_per_topic: BTreeMap::new(),
        first_log_time_ns: None,
        last_log_time_ns: None,
        metadata_records: 0,
        has_drop_counts: false,
    };
    let mut failure = None;
    let scanned = scan_file(input, ScanOptions::default(), |item| {
        let result = match item {
            ScanItem::Metadata(record) => {
                report.metadata_records += 1;
                report.has_drop_counts |= record.name == metadata::DROPS;
                writer.write_metadata(record)
            }
            ScanItem::Message(message) => {
                let channel = &message.channel;
                let id = match channel_ids.get(&channel.id) {
                    Some(id) => Ok(*id),
                    None => add_channel(&mut writer, channel).inspect(|&id| {
                        channel_ids.insert(channel.id, id);
                    }),
                };
                id.and_then(|channel_id| {
                    let header = MessageHeader {
                        channel_id,
                        sequence: message.sequence,
                        log_time: message.log_time,
                        publish_time: message.publish_time,
                    };
                    writer.write_to_known_channel(&header, message.data)
                })
                .map(|()| {
                    *report
                        .messages_per_topic
                        .entry(channel.topic.clone())
                        .or_insert(0) += 1;
                    report.first_log_time_ns.get_or_insert(message.log_time);
                    report.last_log_time_ns = Some(message.log_time);
                })
            }
            ScanItem::Chunk(_) | ScanItem::DamagedChunk(_) => Ok(()),
        };
        match result {
            Ok(()) => ControlFlow::Continue(()),
            Err(error) => {
                failure = Some(mcap_error_text(&error));
                ControlFlow::Break(())
            }
        }
    });
    let finish =
        |writer: &mut Writer<BufWriter<File>>, report: &RecoverReport| -> Result<(), String> {
            let reason = match &report.end {
                ScanEnd::Truncated { reason, .. } => reason.clone(),
                _ => String::new(),
            };
            let record = metadata::record(
                metadata::RECOVERY,
                [
                    ("source", report.input.display().to_string()),
                    ("source_bytes", report.input_bytes.to_string()),
                    ("valid_bytes", report.valid_bytes.to_string()),
                    ("lost_tail_bytes", report.lost_tail_bytes().to_string()),
                    ("damaged_chunks", report.damaged_chunks.len().to_string()),
                    ("recovered_messages", report.messages().to_string()),
                    ("truncation", reason),
                    ("software_version", metadata::SOFTWARE_VERSION.to_owned()),
                ],
            );
            writer
                .write_metadata(&record)
                .map_err(|error| mcap_error_text(&error))?;
            writer.finish().map_err(|error| mcap_error_text(&error))?;
            Ok(())
        };
    let outcome = match (scanned, failure) {
        (Ok(outcome), None) => outcome,
        (Err(error), _) => {
            drop(writer);
            let _ = std::fs::remove_file(&partial);
            return Err(error.into());
        }
        (Ok(_), Some(reason)) => {
            drop(writer);
            let _ = std::fs::remove_file(&partial);
            return Err(write_error(reason));
        }
    };
    report.input_bytes = outcome.file_bytes;
    report.valid_bytes = outcome.valid_bytes;
    report.end = outcome.end;
    report.damaged_chunks = outcome.damaged_chunks;
    if let Err(reason) = finish(&mut writer, &report) {
        drop(writer);
        let _ = std::fs::remove_file(&partial);
        return Err(write_error(reason));
    }
    let mut inner = writer.into_inner();
    if let Err(error) = std::io::Write::flush(&mut inner) {
        drop(inner);
        let _ = std::fs::remove_file(&partial);
        return Err(write_error(error.to_string()));
    }
    drop(inner);
    std::fs::rename(&partial, output)
        .map_err(|error| write_error(format!("renaming {}: {error}", partial.display())))?;
    Ok(report)
}

fn add_channel(
    writer: &mut Writer<BufWriter<File>>,
    channel: &mcap::Channel<'static>,
) -> Result<u16, mcap::McapError> {
    let schema_id = match &channel.schema {
        Some(schema) => writer.add_schema(&schema.name, &schema.encoding, &schema.data)?,
        None => 0,
    };
    writer.add_channel(
        schema_id,
        &channel.topic,
        &channel.message_encoding,
        &channel.metadata,
    )
}
