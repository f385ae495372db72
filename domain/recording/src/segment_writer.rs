//! One MCAP file being written: chunked and compressed, channels registered per file, with the
//! file's size tracked as it grows, and a bound on what finishing it still writes (so a writer
//! can hold that much disk space in reserve and always finish its file).

use crate::mcap_error::mcap_error_text;
use crate::schema::TopicInfo;
use mcap::records::{MessageHeader, Metadata};
use mcap::{McapError, WriteOptions, Writer};
use std::collections::BTreeMap;
use std::io::{Seek, SeekFrom, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Chunk compression of a recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChunkCompression {
    /// zstd (level 1 by default): smaller files, slower than LZ4.
    Zstd,
    /// LZ4 frame: the fastest, the recorder's default.
    Lz4,
    /// Uncompressed chunks.
    None,
}

impl std::str::FromStr for ChunkCompression {
    type Err = String;

    /// `zstd`, `lz4` or `none` (the command line's `--compression`).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        [Self::Zstd, Self::Lz4, Self::None]
            .into_iter()
            .find(|compression| compression.name() == text)
            .ok_or_else(|| format!("unknown compression {text:?} (zstd, lz4 or none)"))
    }
}

impl ChunkCompression {
    pub fn name(self) -> &'static str {
        match self {
            Self::Zstd => "zstd",
            Self::Lz4 => "lz4",
            Self::None => "none",
        }
    }

    fn to_mcap(self) -> Option<mcap::Compression> {
        match self {
            Self::Zstd => Some(mcap::Compression::Zstd),
            Self::Lz4 => Some(mcap::Compression::Lz4),
            Self::None => None,
        }
    }
}

/// How chunks are built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkSettings {
    pub compression: ChunkCompression,
    /// zstd level (1..=22) or LZ4 acceleration level (0 = default).
    pub compression_level: u32,
    /// zstd worker threads: 0 compresses on the writing thread, n > 0 hands compression to n
    /// zstd worker threads (the writing thread then only frames and writes).
    pub compression_threads: u32,
    /// A chunk is closed once its uncompressed content exceeds this many bytes (a single
    /// message larger than this gets a chunk of its own).
    pub chunk_size_bytes: u64,
}

impl ChunkSettings {
    fn write_options(&self) -> WriteOptions {
        WriteOptions::new()
            .profile("harvest")
            .library(format!(
                "harvest-recorder/{} {}",
                crate::metadata::SOFTWARE_VERSION,
                mcap::LIBRARY_IDENTIFIER
            ))
            .compression(self.compression.to_mcap())
            .compression_level(self.compression_level)
            .compression_threads(self.compression_threads)
            .chunk_size(Some(self.chunk_size_bytes.max(1)))
    }
}

/// A `Write + Seek` that records the largest offset written, shared with the owner of the
/// MCAP writer (which owns the stream).
#[derive(Debug)]
pub struct SizeTracked<W> {
    inner: W,
    position: u64,
    end: Arc<AtomicU64>,
}

impl<W: Write + Seek> SizeTracked<W> {
    pub fn new(mut inner: W) -> std::io::Result<(Self, Arc<AtomicU64>)> {
        let position = inner.stream_position()?;
        let end = Arc::new(AtomicU64::new(position));
        Ok((
            Self {
                inner,
                position,
                end: end.clone(),
            },
            end,
        ))
    }

    pub fn into_inner(self) -> W {
        self.inner
    }
}

impl<W: Write> Write for SizeTracked<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let written = self.inner.write(buf)?;
        self.position += written as u64;
        self.end.fetch_max(self.position, Ordering::Relaxed);
        Ok(written)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        self.inner.write_all(buf)?;
        let bytes = buf.len();
        self.position += bytes as u64;
        self.end.fetch_max(self.position, Ordering::Relaxed);
        Ok(())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Seek> Seek for SizeTracked<W> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.position = self.inner.seek(pos)?;
        Ok(self.position)
    }

    fn stream_position(&mut self) -> std::io::Result<u64> {
        Ok(self.position)
    }
}

/// A channel whose messages are not catalogue payloads but carry a schema of their own (the
/// recorder's mapped Foxglove channels: protobuf with a `FileDescriptorSet`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ForeignChannel {
    pub topic: String,
    pub schema_name: String,
    /// `protobuf`, `jsonschema`, ...
    pub schema_encoding: String,
    pub schema_data: Vec<u8>,
    /// `protobuf`, `json`, ...
    pub message_encoding: String,
    pub metadata: BTreeMap<String, String>,
}

/// Bytes of a Message record besides its data: opcode, length, channel id, sequence, two stamps.
const MESSAGE_RECORD_OVERHEAD_BYTES: u64 = 1 + 8 + 2 + 4 + 8 + 8;
/// A Chunk record besides its records (opcode, length, times, sizes, CRC, compression name),
/// rounded up; also covers the compressor's frame headers.
const CHUNK_OVERHEAD_BYTES: u64 = 256;
/// A Chunk Index record without its per-channel offsets, rounded up.
const CHUNK_INDEX_BYTES: u64 = 128;
/// Per channel: an offset in each chunk index, an entry in the statistics, the record of a
/// message index after each chunk (without its entries).
const PER_CHANNEL_BYTES: u64 = 10 + 10 + 16;
/// One entry of a message index.
const MESSAGE_INDEX_ENTRY_BYTES: u64 = 16;
/// A Metadata Index record without the name.
const METADATA_INDEX_BYTES: u64 = 64;
/// Statistics, summary offsets, Data End, Footer and the closing magic, rounded up.
const SUMMARY_FIXED_BYTES: u64 = 2048;
/// Chunks the count below may miss (the MCAP writer closes chunks by its own measure too).
const CHUNK_COUNT_SLACK: u64 = 16;
/// Everything the estimate does not itemize.
const FINISH_SLACK_BYTES: u64 = 64 * 1024;

/// An MCAP writer with the channels of one file.
pub struct SegmentWriter<W: Write + Seek> {
    writer: Writer<SizeTracked<W>>,
    size: Arc<AtomicU64>,
    /// MCAP channel id of each topic index, once added to this file.
    channel_ids: Vec<Option<u16>>,
    messages: u64,
    /// Messages written since the last chunk was closed.
    messages_in_open_chunk: u64,
    /// What [`Self::finish_bound_bytes`] counts.
    finish_estimate: FinishEstimate,
    /// The file holds complete records up to here, handed to the OS (see [`Self::flush`]).
    flushed_bytes: u64,
}

/// The figures that bound what finishing a file still writes.
#[derive(Debug, Clone, Copy, Default)]
struct FinishEstimate {
    chunk_size_bytes: u64,
    /// Uncompressed records in the open chunk (as the MCAP writer measures it, or more).
    open_chunk_bytes: u64,
    /// Chunks closed so far (give or take [`CHUNK_COUNT_SLACK`]).
    chunks: u64,
    channels: u64,
    /// Schema and Channel records, which the summary repeats.
    schema_and_channel_bytes: u64,
    /// The summary's Metadata Index records.
    metadata_index_bytes: u64,
}

impl<W: Write + Seek> SegmentWriter<W> {
    /// Starts an MCAP stream on `inner` for a table of `topic_count` topics.
    pub fn new(inner: W, settings: &ChunkSettings, topic_count: usize) -> Result<Self, String> {
        let (tracked, size) = SizeTracked::new(inner).map_err(|error| error.to_string())?;
        let writer = Writer::with_options(tracked, settings.write_options())
            .map_err(|error| mcap_error_text(&error))?;
        Ok(Self {
            writer,
            size,
            channel_ids: vec![None; topic_count],
            messages: 0,
            messages_in_open_chunk: 0,
            finish_estimate: FinishEstimate {
                chunk_size_bytes: settings.chunk_size_bytes.max(1),
                ..FinishEstimate::default()
            },
            flushed_bytes: 0,
        })
    }

    /// Registers `topic` (index `index` in the topic table) in this file, once.
    pub fn add_channel(&mut self, index: usize, topic: &TopicInfo) -> Result<u16, McapError> {
        if let Some(Some(id)) = self.channel_ids.get(index) {
            return Ok(*id);
        }
        let schema_name = topic.schema_name();
        let schema_data = topic.schema_data();
        let channel_metadata = topic.channel_metadata();
        let schema_id = self.writer.add_schema(
            &schema_name,
            harvest_ipc::codec::ENCODING,
            schema_data.as_bytes(),
        )?;
        let channel_id = self.writer.add_channel(
            schema_id,
            topic.spec.topic,
            harvest_ipc::codec::ENCODING,
            &channel_metadata,
        )?;
        let estimate = &mut self.finish_estimate;
        estimate.channels += 1;
        estimate.schema_and_channel_bytes += Self::schema_and_channel_bytes(
            &schema_name,
            &schema_data,
            topic.spec.topic,
            &channel_metadata,
        );
        if index >= self.channel_ids.len() {
            self.channel_ids.resize(index + 1, None);
        }
        self.channel_ids[index] = Some(channel_id);
        Ok(channel_id)
    }

    /// Registers the foreign channel `channel` under `index` (of the same index space as the
    /// catalogue topics), once.
    pub fn add_foreign_channel(
        &mut self,
        index: usize,
        channel: &ForeignChannel,
    ) -> Result<u16, McapError> {
        if let Some(Some(id)) = self.channel_ids.get(index) {
            return Ok(*id);
        }
        let schema_id = self.writer.add_schema(
            &channel.schema_name,
            &channel.schema_encoding,
            &channel.schema_data,
        )?;
        let channel_id = self.writer.add_channel(
            schema_id,
            &channel.topic,
            &channel.message_encoding,
            &channel.metadata,
        )?;
        let estimate = &mut self.finish_estimate;
        estimate.channels += 1;
        // The same records as a catalogue channel's; the encodings are their own (counted on
        // top of the codec's: an over-estimate keeps the reservation on the safe side).
        estimate.schema_and_channel_bytes += Self::schema_and_channel_bytes(
            &channel.schema_name,
            "",
            &channel.topic,
            &channel.metadata,
        ) + (channel.schema_data.len()
            + channel.schema_encoding.len()
            + channel.message_encoding.len())
            as u64;
        if index >= self.channel_ids.len() {
            self.channel_ids.resize(index + 1, None);
        }
        self.channel_ids[index] = Some(channel_id);
        Ok(channel_id)
    }

    /// Writes one message of the foreign channel `index` (added on first use).
    pub fn write_foreign_message(
        &mut self,
        index: usize,
        channel: &ForeignChannel,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &[u8],
    ) -> Result<(), McapError> {
        let channel_id = self.add_foreign_channel(index, channel)?;
        self.write_on(channel_id, sequence, log_time_ns, publish_time_ns, data)
    }

    fn write_on(
        &mut self,
        channel_id: u16,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &[u8],
    ) -> Result<(), McapError> {
        // The MCAP writer closes the open chunk before a message once the chunk holds more
        // than the chunk size: count that chunk.
        let estimate = &mut self.finish_estimate;
        if estimate.open_chunk_bytes > estimate.chunk_size_bytes {
            estimate.open_chunk_bytes = 0;
            estimate.chunks += 1;
        }
        estimate.open_chunk_bytes += MESSAGE_RECORD_OVERHEAD_BYTES + data.len() as u64;
        let header = MessageHeader {
            channel_id,
            sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        self.writer.write_to_known_channel(&header, data)?;
        self.messages += 1;
        self.messages_in_open_chunk += 1;
        Ok(())
    }

    /// Writes one message of topic `index` (added on first use).
    pub fn write_message(
        &mut self,
        index: usize,
        topic: &TopicInfo,
        sequence: u32,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &[u8],
    ) -> Result<(), McapError> {
        let channel_id = self.add_channel(index, topic)?;
        self.write_on(channel_id, sequence, log_time_ns, publish_time_ns, data)
    }

    pub fn write_metadata(&mut self, metadata: &Metadata) -> Result<(), McapError> {
        // Writing metadata closes the open chunk first.
        self.count_chunk_closed();
        self.finish_estimate.metadata_index_bytes +=
            METADATA_INDEX_BYTES + metadata.name.len() as u64;
        self.writer.write_metadata(metadata)
    }

    /// Closes the open chunk (if it holds messages) and hands its bytes to the OS: after this,
    /// a crash loses nothing written so far.
    pub fn close_chunk(&mut self) -> Result<(), McapError> {
        if self.messages_in_open_chunk == 0 {
            return Ok(());
        }
        self.flush()
    }

    /// Closes the open chunk (if any) and hands everything written to the OS: the file then
    /// holds complete records up to [`Self::flushed_bytes`].
    pub fn flush(&mut self) -> Result<(), McapError> {
        self.count_chunk_closed();
        self.writer.flush()?;
        self.flushed_bytes = self.size_bytes();
        Ok(())
    }

    /// The file's bytes up to the last successful [`Self::flush`]: complete records, in the
    /// file. After a write error the file can be cut back to this and sealed
    /// ([`crate::seal::seal_cut_file`]).
    pub fn flushed_bytes(&self) -> u64 {
        self.flushed_bytes
    }

    /// An upper bound on the bytes the file still grows by if a message of `message_bytes`
    /// is written and the file is then finished: the rest of the open chunk and the message
    /// (compressed output can exceed its input a little), their message indexes, and the
    /// summary (schemas and channels again, one index per chunk and metadata record,
    /// statistics) with the footer. A writer that keeps this much disk space in hand can
    /// always finish its file.
    pub fn finish_bound_bytes(&self, message_bytes: u64) -> u64 {
        let estimate = &self.finish_estimate;
        let channels = estimate.channels + 1;
        let chunk_content =
            estimate.open_chunk_bytes + MESSAGE_RECORD_OVERHEAD_BYTES + message_bytes;
        let chunks_data = chunk_content + chunk_content / 64 + 2 * CHUNK_OVERHEAD_BYTES;
        let message_indexes = MESSAGE_INDEX_ENTRY_BYTES * (self.messages_in_open_chunk + 1)
            + 2 * channels * PER_CHANNEL_BYTES;
        let chunk_indexes = (estimate.chunks + CHUNK_COUNT_SLACK)
            * (CHUNK_INDEX_BYTES + channels * PER_CHANNEL_BYTES);
        let summary = estimate.schema_and_channel_bytes
            + chunk_indexes
            + estimate.metadata_index_bytes
            + SUMMARY_FIXED_BYTES;
        chunks_data + message_indexes + summary + FINISH_SLACK_BYTES
    }

    fn count_chunk_closed(&mut self) {
        if self.messages_in_open_chunk > 0 || self.finish_estimate.open_chunk_bytes > 0 {
            self.finish_estimate.chunks += 1;
        }
        self.messages_in_open_chunk = 0;
        self.finish_estimate.open_chunk_bytes = 0;
    }

    /// Bytes of a Schema and a Channel record (each appears in the data section and again in
    /// the summary).
    fn schema_and_channel_bytes(
        schema_name: &str,
        schema_data: &str,
        topic: &str,
        channel_metadata: &std::collections::BTreeMap<String, String>,
    ) -> u64 {
        let metadata_bytes: usize = channel_metadata
            .iter()
            .map(|(key, value)| 8 + key.len() + value.len())
            .sum();
        let encoding = harvest_ipc::codec::ENCODING.len();
        let schema = 9 + 2 + 4 + schema_name.len() + 4 + encoding + 4 + schema_data.len();
        let channel = 9 + 2 + 2 + 4 + topic.len() + 4 + encoding + 4 + metadata_bytes;
        (schema + channel) as u64
    }

    /// Whether the open chunk holds messages not yet closed.
    pub fn has_open_chunk(&self) -> bool {
        self.messages_in_open_chunk > 0
    }

    /// Bytes in the file so far (compressed chunks, records and indexes).
    pub fn size_bytes(&self) -> u64 {
        self.size.load(Ordering::Relaxed)
    }

    pub fn message_count(&self) -> u64 {
        self.messages
    }

    /// Gives the stream back without finishing the file (after a write error: the file then
    /// holds its complete chunks, which `rec recover` reads).
    pub fn into_stream(self) -> W {
        self.writer.into_inner().into_inner()
    }

    /// Writes the summary, footer and end magic, flushes, and returns the stream.
    pub fn finish(mut self) -> Result<W, McapError> {
        self.writer.finish()?;
        let mut tracked = self.writer.into_inner();
        tracked.flush()?;
        Ok(tracked.into_inner())
    }
}
