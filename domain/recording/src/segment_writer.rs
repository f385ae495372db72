//! One MCAP file being written: chunked and compressed, channels registered per file, with the
//! file's size tracked as it grows.

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

/// An MCAP writer with the channels of one file.
pub struct SegmentWriter<W: Write + Seek> {
    writer: Writer<SizeTracked<W>>,
    size: Arc<AtomicU64>,
    /// MCAP channel id of each topic index, once added to this file.
    channel_ids: Vec<Option<u16>>,
    messages: u64,
    /// Messages written since the last chunk was closed.
    messages_in_open_chunk: u64,
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
        })
    }

    /// Registers `topic` (index `index` in the topic table) in this file, once.
    pub fn add_channel(&mut self, index: usize, topic: &TopicInfo) -> Result<u16, McapError> {
        if let Some(Some(id)) = self.channel_ids.get(index) {
            return Ok(*id);
        }
        let schema_id = self.writer.add_schema(
            &topic.schema_name(),
            harvest_ipc::codec::ENCODING,
            topic.schema_data().as_bytes(),
        )?;
        let channel_id = self.writer.add_channel(
            schema_id,
            topic.spec.topic,
            harvest_ipc::codec::ENCODING,
            &topic.channel_metadata(),
        )?;
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
        self.messages_in_open_chunk = 0;
        self.writer.write_metadata(metadata)
    }

    /// Closes the open chunk (if it holds messages) and hands its bytes to the OS: after this,
    /// a crash loses nothing written so far.
    pub fn close_chunk(&mut self) -> Result<(), McapError> {
        if self.messages_in_open_chunk == 0 {
            return Ok(());
        }
        self.messages_in_open_chunk = 0;
        self.writer.flush()
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
