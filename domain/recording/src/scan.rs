//! A streaming, damage-tolerant reader of MCAP files: every tool that reads recordings goes
//! through it.
//!
//! It walks the data section record by record (memory bounded by the largest chunk), keeping the
//! exact byte offset of the last complete record. Each chunk is decompressed into a reused
//! buffer of its declared size and its CRC checked *before* any of its records are parsed, and
//! inner records are bounds-checked; a damaged chunk is skipped and reported while reading goes
//! on with the next record. A file cut mid-record (a recorder killed while writing a chunk) ends
//! the scan at the last complete record, with the cut described. Nothing here panics on bad
//! input.

use crate::record_lengths::{RECORD_PREFIX_BYTES, RecordSplit, split_record};
use crate::recording_file::{ReadError, open_recording};
use mcap::read::ChannelAccumulator;
use mcap::records::{ChunkHeader, Metadata, Record, op};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::borrow::Cow;
use std::io::Read;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Arc;

/// A chunk declaring more uncompressed bytes than this is treated as damaged.
const MAX_CHUNK_UNCOMPRESSED_BYTES: u64 = 4 << 30;

/// What to read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScanOptions {
    /// Only chunks overlapping this inclusive `log_time` range are decompressed (messages are
    /// still delivered whole-chunk: callers filter per message).
    pub log_time_window: Option<(u64, u64)>,
}

/// One message, borrowed from the scanner's buffers.
#[derive(Debug, Clone)]
pub struct ScannedMessage<'a> {
    pub channel: Arc<mcap::Channel<'static>>,
    pub sequence: u32,
    pub log_time: u64,
    pub publish_time: u64,
    pub data: &'a [u8],
}

/// A chunk as found in the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChunkInfo {
    /// Byte offset of the chunk record.
    pub offset: u64,
    /// Size of the whole chunk record in the file.
    pub record_bytes: u64,
    pub compression: String,
    pub compressed_bytes: u64,
    pub uncompressed_bytes: u64,
    pub message_start_time: u64,
    pub message_end_time: u64,
    /// Outside the requested time window: its messages are not delivered (and it is not even
    /// decompressed when the summary already lists every channel).
    pub skipped: bool,
}

/// A complete chunk whose content could not be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DamagedChunk {
    pub offset: u64,
    pub record_bytes: u64,
    pub message_start_time: u64,
    pub message_end_time: u64,
    /// Messages delivered from it before the damage was found (0 when the CRC caught it).
    pub messages_read: u64,
    pub reason: String,
}

/// What the scanner hands to its caller, in file order.
#[derive(Debug)]
pub enum ScanItem<'a> {
    Message(ScannedMessage<'a>),
    Metadata(&'a Metadata),
    /// Before the chunk's messages.
    Chunk(&'a ChunkInfo),
    DamagedChunk(&'a DamagedChunk),
}

/// How the data section ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ScanEnd {
    /// The data-end record was reached: the data section is complete.
    Complete,
    /// The file ends early (or turns unreadable) at `offset`; everything before is read.
    Truncated { offset: u64, reason: String },
    /// The caller stopped the scan.
    Stopped,
}

/// The result of a scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScanOutcome {
    pub file_bytes: u64,
    /// Offset just past the last complete record read.
    pub valid_bytes: u64,
    pub end: ScanEnd,
    pub damaged_chunks: Vec<DamagedChunk>,
    pub messages: u64,
    /// Messages naming a channel never defined (skipped).
    pub orphan_messages: u64,
    /// Non-fatal oddities (conflicting channel records and the like).
    pub warnings: Vec<String>,
}

impl ScanOutcome {
    /// True when the data section was read completely with no damaged chunk.
    pub fn is_intact(&self) -> bool {
        self.end == ScanEnd::Complete && self.damaged_chunks.is_empty()
    }

    /// Bytes at the end of the file that could not be read (0 when complete).
    pub fn lost_tail_bytes(&self) -> u64 {
        match self.end {
            ScanEnd::Truncated { offset, .. } => self.file_bytes.saturating_sub(offset),
            ScanEnd::Complete | ScanEnd::Stopped => 0,
        }
    }
}

/// Scans the file at `path`, calling `on_item` for every message, metadata record and chunk.
pub fn scan_file(
    path: &Path,
    options: ScanOptions,
    on_item: impl FnMut(ScanItem<'_>) -> ControlFlow<()>,
) -> Result<ScanOutcome, ReadError> {
    let (file, file_bytes) = open_recording(path)?;
    let mut scanner = Scanner::new(file_bytes, options);
    // Chunks outside the window can only be skipped unread when every channel is already known
    // (channel records live inside chunks): take them from the summary when there is one.
    if options.log_time_window.is_some()
        && let Ok(Some(summary)) = crate::recording_file::read_summary(path)
    {
        scanner.channels = ChannelAccumulator::from_summary(&summary);
        scanner.channels_known = true;
    }
    scanner.run(
        path,
        std::io::BufReader::with_capacity(1 << 20, file),
        on_item,
    )
}

struct Scanner {
    options: ScanOptions,
    channels: ChannelAccumulator<'static>,
    chunk_buffer: Vec<u8>,
    zstd: Option<zstd::bulk::Decompressor<'static>>,
    /// Every channel is known up front (from the summary).
    channels_known: bool,
    outcome: ScanOutcome,
}

enum Step {
    Continue,
    Stop,
}

impl Scanner {
    fn new(file_bytes: u64, options: ScanOptions) -> Self {
        Self {
            options,
            channels: ChannelAccumulator::default(),
            chunk_buffer: Vec::new(),
            zstd: None,
            channels_known: false,
            outcome: ScanOutcome {
                file_bytes,
                valid_bytes: mcap::MAGIC.len() as u64,
                end: ScanEnd::Stopped,
                damaged_chunks: Vec::new(),
                messages: 0,
                orphan_messages: 0,
                warnings: Vec::new(),
            },
        }
    }

    fn run(
        &mut self,
        path: &Path,
        mut source: impl Read,
        mut on_item: impl FnMut(ScanItem<'_>) -> ControlFlow<()>,
    ) -> Result<ScanOutcome, ReadError> {
        let limit = usize::try_from(self.outcome.file_bytes).unwrap_or(usize::MAX);
        let mut reader = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_skip_start_magic(true)
                .with_skip_end_magic(true)
                .with_emit_chunks(true)
                .with_record_length_limit(limit),
        );
        // open_recording checked the magic and left the file just past it.
        let mut offset = mcap::MAGIC.len() as u64;
        loop {
            let event = match reader.next_event() {
                None => {
                    self.outcome.end = ScanEnd::Truncated {
                        offset,
                        reason: "the file ends after a complete record, without the data-end \
record and summary (the recorder did not finish it)"
                            .to_owned(),
                    };
                    break;
                }
                Some(Err(error)) => {
                    self.outcome.end = ScanEnd::Truncated {
                        offset,
                        reason: truncation_reason(&error, offset, self.outcome.file_bytes),
                    };
                    break;
                }
                Some(Ok(event)) => event,
            };
            match event {
                LinearReadEvent::ReadRequest(need) => {
                    let buffer = reader.insert(need);
                    let read = loop {
                        match source.read(buffer) {
                            Ok(read) => break read,
                            Err(error) if error.kind() == std::io::ErrorKind::Interrupted => {
                                continue;
                            }
                            Err(source) => {
                                return Err(ReadError::Read {
                                    path: path.to_path_buf(),
                                    source,
                                });
                            }
                        }
                    };
                    reader.notify_read(read);
                }
                LinearReadEvent::Record { opcode, data } => {
                    let record_offset = offset;
                    offset += (RECORD_PREFIX_BYTES + data.len()) as u64;
                    if opcode == op::DATA_END {
                        self.outcome.valid_bytes = offset;
                        self.outcome.end = ScanEnd::Complete;
                        break;
                    }
                    let step = self.on_record(opcode, data, record_offset, &mut on_item);
                    self.outcome.valid_bytes = offset;
                    if let Step::Stop = step {
                        self.outcome.end = ScanEnd::Stopped;
                        break;
                    }
                }
            }
        }
        Ok(std::mem::replace(
            &mut self.outcome,
            ScanOutcome {
                file_bytes: 0,
                valid_bytes: 0,
                end: ScanEnd::Stopped,
                damaged_chunks: Vec::new(),
                messages: 0,
                orphan_messages: 0,
                warnings: Vec::new(),
            },
        ))
    }

    fn on_record(
        &mut self,
        opcode: u8,
        data: &[u8],
        offset: u64,
        on_item: &mut impl FnMut(ScanItem<'_>) -> ControlFlow<()>,
    ) -> Step {
        if opcode == op::CHUNK {
            let record_bytes = (RECORD_PREFIX_BYTES + data.len()) as u64;
            return match crate::record_lengths::parse_record(opcode, data) {
                Ok(Record::Chunk { header, data }) => {
                    self.on_chunk(header, &data, offset, record_bytes, on_item)
                }
                Ok(_) | Err(_) => {
                    let damaged = DamagedChunk {
                        offset,
                        record_bytes: (RECORD_PREFIX_BYTES + data.len()) as u64,
                        message_start_time: 0,
                        message_end_time: 0,
                        messages_read: 0,
                        reason: "unreadable chunk header".to_owned(),
                    };
                    self.report_damaged(damaged, on_item)
                }
            };
        }
        self.on_plain_record(opcode, data, true, on_item)
            .unwrap_or(Step::Continue)
    }

    /// A record outside a chunk or inside one; with `deliver` false only schemas and channels
    /// are taken in. `None` when the record was unparseable.
    fn on_plain_record(
        &mut self,
        opcode: u8,
        data: &[u8],
        deliver: bool,
        on_item: &mut impl FnMut(ScanItem<'_>) -> ControlFlow<()>,
    ) -> Option<Step> {
        if !deliver && opcode != op::SCHEMA && opcode != op::CHANNEL {
            return Some(Step::Continue);
        }
        let record = match crate::record_lengths::parse_record(opcode, data) {
            Ok(record) => record,
            Err(error) => {
                self.outcome.warnings.push(format!(
                    "unreadable record (opcode 0x{opcode:02x}): {error}"
                ));
                return None;
            }
        };
        let flow = match record {
            Record::Schema { header, data } => {
                let name = header.name.clone();
                if let Err(error) = self
                    .channels
                    .add_schema(header, Cow::Owned(data.into_owned()))
                {
                    self.outcome
                        .warnings
                        .push(format!("schema {name:?}: {error}"));
                }
                ControlFlow::Continue(())
            }
            Record::Channel(channel) => {
                let topic = channel.topic.clone();
                if let Err(error) = self.channels.add_channel(channel) {
                    self.outcome
                        .warnings
                        .push(format!("channel {topic:?}: {error}"));
                }
                ControlFlow::Continue(())
            }
            Record::Message { header, data } => match self.channels.get(header.channel_id) {
                Some(channel) => {
                    self.outcome.messages += 1;
                    on_item(ScanItem::Message(ScannedMessage {
                        channel,
                        sequence: header.sequence,
                        log_time: header.log_time,
                        publish_time: header.publish_time,
                        data: &data,
                    }))
                }
                None => {
                    self.outcome.orphan_messages += 1;
                    ControlFlow::Continue(())
                }
            },
            Record::Metadata(metadata) => on_item(ScanItem::Metadata(&metadata)),
            _ => ControlFlow::Continue(()),
        };
        Some(match flow {
            ControlFlow::Continue(()) => Step::Continue,
            ControlFlow::Break(()) => Step::Stop,
        })
    }

    fn on_chunk(
        &mut self,
        header: ChunkHeader,
        compressed: &[u8],
        offset: u64,
        record_bytes: u64,
        on_item: &mut impl FnMut(ScanItem<'_>) -> ControlFlow<()>,
    ) -> Step {
        let skipped = self.options.log_time_window.is_some_and(|(start, end)| {
            header.message_end_time < start || header.message_start_time > end
        });
        let info = ChunkInfo {
            offset,
            record_bytes,
            compression: header.compression.clone(),
            compressed_bytes: header.compressed_size,
            uncompressed_bytes: header.uncompressed_size,
            message_start_time: header.message_start_time,
            message_end_time: header.message_end_time,
            skipped,
        };
        if on_item(ScanItem::Chunk(&info)).is_break() {
            return Step::Stop;
        }
        if skipped && self.channels_known {
            return Step::Continue;
        }
        let mut damaged = DamagedChunk {
            offset,
            record_bytes,
            message_start_time: header.message_start_time,
            message_end_time: header.message_end_time,
            messages_read: 0,
            reason: String::new(),
        };
        if let Err(reason) = self.decompress(&header, compressed) {
            damaged.reason = reason;
            return self.report_damaged(damaged, on_item);
        }
        let content = std::mem::take(&mut self.chunk_buffer);
        let mut position = 0usize;
        let mut step = Step::Continue;
        let messages_before = self.outcome.messages;
        while position < content.len() {
            let (opcode, body, rest) = match split_record(&content[position..]) {
                RecordSplit::Whole { opcode, body, rest } => (opcode, body, rest),
                RecordSplit::PrefixCut => {
                    damaged.reason =
                        format!("record header cut at byte {position} of the chunk content");
                    break;
                }
                RecordSplit::PastEnd {
                    claimed_bytes: length,
                } => {
                    damaged.reason = format!(
                        "record at byte {position} of the chunk content claims {length} bytes, past the chunk's end"
                    );
                    break;
                }
            };
            match self.on_plain_record(opcode, body, !skipped, on_item) {
                Some(Step::Continue) => {}
                Some(Step::Stop) => {
                    step = Step::Stop;
                    break;
                }
                None => {
                    damaged.reason = format!(
                        "unparseable record (opcode 0x{opcode:02x}) at byte {position} of the chunk content"
                    );
                    break;
                }
            }
            position = content.len() - rest.len();
        }
        self.chunk_buffer = content;
        if !damaged.reason.is_empty() {
            damaged.messages_read = self.outcome.messages - messages_before;
            if let Step::Stop = self.report_damaged(damaged, on_item) {
                return Step::Stop;
            }
        }
        step
    }

    fn report_damaged(
        &mut self,
        damaged: DamagedChunk,
        on_item: &mut impl FnMut(ScanItem<'_>) -> ControlFlow<()>,
    ) -> Step {
        tracing::warn!(offset = damaged.offset, reason = %damaged.reason, "damaged chunk skipped");
        let flow = on_item(ScanItem::DamagedChunk(&damaged));
        self.outcome.damaged_chunks.push(damaged);
        if flow.is_break() {
            Step::Stop
        } else {
            Step::Continue
        }
    }

    /// Decompresses a chunk into `chunk_buffer` and checks its CRC.
    fn decompress(&mut self, header: &ChunkHeader, compressed: &[u8]) -> Result<(), String> {
        if header.uncompressed_size > MAX_CHUNK_UNCOMPRESSED_BYTES {
            return Err(format!(
                "declares {} uncompressed bytes",
                header.uncompressed_size
            ));
        }
        let expected = header.uncompressed_size as usize;
        self.chunk_buffer.clear();
        self.chunk_buffer
            .try_reserve_exact(expected)
            .map_err(|_| format!("cannot allocate {expected} bytes to decompress it"))?;
        match header.compression.as_str() {
            "" => self.chunk_buffer.extend_from_slice(compressed),
            "zstd" => {
                if self.zstd.is_none() {
                    let decompressor = zstd::bulk::Decompressor::new()
                        .map_err(|error| format!("zstd: {error}"))?;
                    self.zstd = Some(decompressor);
                }
                let Some(decompressor) = self.zstd.as_mut() else {
                    return Err("zstd decoder unavailable".to_owned());
                };
                decompressor
                    .decompress_to_buffer(compressed, &mut self.chunk_buffer)
                    .map_err(|error| format!("zstd: {error}"))?;
            }
            "lz4" => {
                let decoder =
                    lz4::Decoder::new(compressed).map_err(|error| format!("lz4: {error}"))?;
                decoder
                    .take(header.uncompressed_size)
                    .read_to_end(&mut self.chunk_buffer)
                    .map_err(|error| format!("lz4: {error}"))?;
            }
            other => return Err(format!("unsupported compression {other:?}")),
        }
        if self.chunk_buffer.len() != expected {
            return Err(format!(
                "decompressed to {} bytes, header says {expected}",
                self.chunk_buffer.len()
            ));
        }
        if header.uncompressed_crc != 0 {
            let crc = crc32fast::hash(&self.chunk_buffer);
            if crc != header.uncompressed_crc {
                return Err(format!(
                    "CRC mismatch (stored {:08x}, computed {crc:08x})",
                    header.uncompressed_crc
                ));
            }
        }
        Ok(())
    }
}

fn truncation_reason(error: &mcap::McapError, offset: u64, file_bytes: u64) -> String {
    let remaining = file_bytes.saturating_sub(offset);
    match error {
        mcap::McapError::RecordTooLarge { opcode, len }
            if *opcode == op::CHUNK && *len == u64::MAX =>
        {
            format!(
                "a chunk starting at byte {offset} was never completed (the recorder stopped while \
writing it); its {remaining} byte(s) are lost"
            )
        }
        mcap::McapError::RecordTooLarge { opcode, len } => format!(
            "a record (opcode 0x{opcode:02x}) at byte {offset} claims {len} bytes but only {remaining} \
remain (the file was cut)"
        ),
        mcap::McapError::UnexpectedEof => {
            format!(
                "the file ends inside the record at byte {offset} ({remaining} byte(s) incomplete)"
            )
        }
        other => format!(
            "unreadable data at byte {offset}: {}",
            crate::mcap_error::mcap_error_text(other)
        ),
    }
}
