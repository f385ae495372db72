//! `harvest rec info`: what a recording holds (channels, types, counts, rates, duration, size,
//! compression, metadata) and whether it is complete.

use crate::metadata;
use crate::recording_file::{ReadError, open_recording, read_indexed_metadata, read_summary};
use crate::scan::{ScanEnd, ScanItem, ScanOptions, scan_file};
use crate::time_base::FileTimeBase;
use crate::units::format_bytes;
use crate::wall_clock::format_utc_iso;
use mcap::records::Metadata;
use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

/// One channel of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelInfo {
    pub topic: String,
    pub schema: String,
    pub message_encoding: String,
    pub messages: u64,
    /// Messages per second over the recording's duration.
    pub rate_hz: f64,
}

/// Chunks of one compression.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CompressionInfo {
    pub chunks: u64,
    pub compressed_bytes: u64,
    pub uncompressed_bytes: u64,
}

/// Everything `rec info` reports.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingInfo {
    pub path: PathBuf,
    pub file_bytes: u64,
    /// The file has a readable summary (it was finished by its writer).
    pub indexed: bool,
    /// Why the file is not complete or fully readable (empty when it is).
    pub problems: Vec<String>,
    pub messages: u64,
    pub start_ns: u64,
    pub end_ns: u64,
    pub channels: Vec<ChannelInfo>,
    /// By compression name (`""` = uncompressed).
    pub compression: BTreeMap<String, CompressionInfo>,
    pub metadata: Vec<Metadata>,
}

impl RecordingInfo {
    pub fn duration_s(&self) -> f64 {
        self.end_ns.saturating_sub(self.start_ns) as f64 * 1e-9
    }

    /// The software version recorded in `harvest.recording`, if any.
    pub fn software_version(&self) -> Option<&str> {
        self.metadata
            .iter()
            .find(|record| record.name == metadata::RECORDING)
            .and_then(|record| record.metadata.get("software_version"))
            .map(String::as_str)
    }
}

/// `rec info` failed.
#[derive(Debug, thiserror::Error)]
pub enum InfoError {
    #[error(transparent)]
    Read(#[from] ReadError),
}

/// Reads what `rec info` shows: from the summary when the file has one, else by scanning it.
pub fn info(path: &Path) -> Result<RecordingInfo, InfoError> {
    let (_, file_bytes) = open_recording(path)?;
    let mut info = RecordingInfo {
        path: path.to_path_buf(),
        file_bytes,
        indexed: false,
        problems: Vec::new(),
        messages: 0,
        start_ns: 0,
        end_ns: 0,
        channels: Vec::new(),
        compression: BTreeMap::new(),
        metadata: Vec::new(),
    };
    match read_summary(path) {
        Ok(Some(summary)) if summary.stats.is_some() => {
            info.indexed = true;
            let stats = summary.stats.clone().unwrap_or_default();
            info.messages = stats.message_count;
            info.start_ns = stats.message_start_time;
            info.end_ns = stats.message_end_time;
            let mut channels: Vec<_> = summary.channels.values().collect();
            channels.sort_by(|a, b| a.topic.cmp(&b.topic));
            for channel in channels {
                info.channels.push(ChannelInfo {
                    topic: channel.topic.clone(),
                    schema: channel
                        .schema
                        .as_ref()
                        .map(|schema| schema.name.clone())
                        .unwrap_or_default(),
                    message_encoding: channel.message_encoding.clone(),
                    messages: stats
                        .channel_message_counts
                        .get(&channel.id)
                        .copied()
                        .unwrap_or(0),
                    rate_hz: 0.0,
                });
            }
            for chunk in &summary.chunk_indexes {
                let entry = info
                    .compression
                    .entry(chunk.compression.clone())
                    .or_default();
                entry.chunks += 1;
                entry.compressed_bytes += chunk.compressed_size;
                entry.uncompressed_bytes += chunk.uncompressed_size;
            }
            match read_indexed_metadata(path, &summary.metadata_indexes) {
                Ok(records) => info.metadata = records,
                Err(problem) => info
                    .problems
                    .push(format!("metadata unreadable: {problem}")),
            }
        }
        Ok(_) => {
            info.problems.push(
                "no summary section: the writer did not finish the file (read by scanning it)"
                    .to_owned(),
            );
            scan_into(path, &mut info)?;
        }
        Err(problem) => {
            info.problems.push(format!(
                "no usable summary ({problem}): read by scanning the file"
            ));
            scan_into(path, &mut info)?;
        }
    }
    let duration_s = info.duration_s();
    for channel in &mut info.channels {
        channel.rate_hz = if duration_s > 0.0 {
            channel.messages as f64 / duration_s
        } else {
            0.0
        };
    }
    Ok(info)
}

fn scan_into(path: &Path, info: &mut RecordingInfo) -> Result<(), ReadError> {
    let mut channels: BTreeMap<String, ChannelInfo> = BTreeMap::new();
    let mut start_ns = u64::MAX;
    let mut end_ns = 0;
    let outcome = scan_file(path, ScanOptions::default(), |item| {
        match item {
            ScanItem::Message(message) => {
                start_ns = start_ns.min(message.log_time);
                end_ns = end_ns.max(message.log_time);
                let channel = &message.channel;
                channels
                    .entry(channel.topic.clone())
                    .or_insert_with(|| ChannelInfo {
                        topic: channel.topic.clone(),
                        schema: channel
                            .schema
                            .as_ref()
                            .map(|schema| schema.name.clone())
                            .unwrap_or_default(),
                        message_encoding: channel.message_encoding.clone(),
                        messages: 0,
                        rate_hz: 0.0,
                    })
                    .messages += 1;
            }
            ScanItem::Metadata(record) => info.metadata.push(record.clone()),
            ScanItem::Chunk(chunk) => {
                let entry = info
                    .compression
                    .entry(chunk.compression.clone())
                    .or_default();
                entry.chunks += 1;
                entry.compressed_bytes += chunk.compressed_bytes;
                entry.uncompressed_bytes += chunk.uncompressed_bytes;
            }
            ScanItem::DamagedChunk(_) => {}
        }
        ControlFlow::Continue(())
    })?;
    info.messages = outcome.messages;
    if outcome.messages > 0 {
        info.start_ns = start_ns;
        info.end_ns = end_ns;
    }
    info.channels = channels.into_values().collect();
    if let ScanEnd::Truncated { reason, .. } = &outcome.end {
        info.problems.push(format!(
            "{reason}; `harvest rec recover` rewrites the readable part into a valid file"
        ));
    }
    for damaged in &outcome.damaged_chunks {
        info.problems.push(format!(
            "damaged chunk at byte {}: {}",
            damaged.offset, damaged.reason
        ));
    }
    info.problems.extend(outcome.warnings);
    Ok(())
}

impl std::fmt::Display for RecordingInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "file:        {} ({})",
            self.path.display(),
            format_bytes(self.file_bytes)
        )?;
        if self.problems.is_empty() {
            writeln!(f, "status:      complete (indexed)")?;
        } else {
            for problem in &self.problems {
                writeln!(f, "status:      {problem}")?;
            }
        }
        if let Some(version) = self.software_version() {
            let note = if version == metadata::SOFTWARE_VERSION {
                ""
            } else {
                " (differs from this build)"
            };
            writeln!(
                f,
                "software:    harvest {version}{note}; this build {}",
                metadata::SOFTWARE_VERSION
            )?;
        }
        let mut time = FileTimeBase::default();
        self.metadata.iter().for_each(|record| time.observe(record));
        let start = match time.realtime_ns(self.start_ns) {
            Some(realtime_ns) => format!(" from {}", format_utc_iso(realtime_ns)),
            None => String::new(),
        };
        writeln!(f, "duration:    {:.3} s{start}", self.duration_s())?;
        writeln!(f, "messages:    {}", self.messages)?;
        for (name, compression) in &self.compression {
            let name = if name.is_empty() {
                "none"
            } else {
                name.as_str()
            };
            let ratio = if compression.uncompressed_bytes > 0 {
                compression.compressed_bytes as f64 / compression.uncompressed_bytes as f64 * 100.0
            } else {
                0.0
            };
            writeln!(
                f,
                "compression: {name}: {} chunk(s), {} -> {} ({ratio:.0}%)",
                compression.chunks,
                format_bytes(compression.uncompressed_bytes),
                format_bytes(compression.compressed_bytes)
            )?;
        }
        writeln!(f, "channels:")?;
        writeln!(
            f,
            "  {:<24} {:<28} {:>10} {:>10}",
            "topic", "schema", "messages", "rate_hz"
        )?;
        for channel in &self.channels {
            writeln!(
                f,
                "  {:<24} {:<28} {:>10} {:>10.2}",
                channel.topic, channel.schema, channel.messages, channel.rate_hz
            )?;
        }
        if !self.metadata.is_empty() {
            writeln!(f, "metadata:")?;
            for record in &self.metadata {
                writeln!(f, "  {}: {}", record.name, describe_metadata(record))?;
            }
        }
        Ok(())
    }
}

/// One line summarizing a metadata record for `rec info`.
fn describe_metadata(record: &Metadata) -> String {
    let entries = &record.metadata;
    let pick = |keys: &[&str]| -> String {
        keys.iter()
            .filter_map(|key| {
                entries
                    .get(*key)
                    .filter(|value| !value.is_empty())
                    .map(|value| format!("{key}={value}"))
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match record.name.as_str() {
        metadata::RECORDING => pick(&[
            "domain",
            "recorder",
            "host",
            "segment",
            "session_started_utc",
            "compression",
            "compression_level",
            "layers",
            "include",
            "exclude",
        ]),
        metadata::EVENTS => entries
            .iter()
            .map(|(kind, count)| format!("{kind}={count}"))
            .collect::<Vec<_>>()
            .join(", "),
        metadata::CLIP => pick(&[
            "triggers",
            "first_trigger_utc",
            "window_s",
            "covered_s",
            "messages",
            "texts",
        ]),
        metadata::CLOCK => pick(&["realtime_utc", "monotonic_ns", metadata::LOG_TIME_OFFSET_NS]),
        metadata::DROPS => {
            let mut lines = Vec::new();
            let mut total = 0u64;
            for (key, value) in entries {
                let count: u64 = value.parse().unwrap_or(0);
                if count > 0
                    && (key.ends_with(".dropped_buffer") || key.ends_with(".dropped_queue"))
                {
                    total += count;
                    lines.push(format!("{key}={count}"));
                }
                if key.ends_with(".not_recorded") {
                    lines.push(format!("{key}: {value}"));
                }
            }
            if lines.is_empty() {
                "no message dropped".to_owned()
            } else {
                format!("{total} dropped: {}", lines.join(", "))
            }
        }
        metadata::LAUNCH | metadata::CALIBRATION => {
            let lines = entries
                .get("text")
                .map(|text| text.lines().count())
                .unwrap_or(0);
            format!("{} ({lines} line(s))", pick(&["path", "error"]))
        }
        metadata::SCENARIO => pick(&["scenario", "error"]),
        _ => entries
            .iter()
            .map(|(key, value)| {
                let mut value = value.clone();
                if value.len() > 40 {
                    value.truncate(value.floor_char_boundary(40));
                    value.push_str("...");
                }
                format!("{key}={value}")
            })
            .collect::<Vec<_>>()
            .join(", "),
    }
}
