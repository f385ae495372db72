//! Re-encoding a recording for Foxglove, which only decodes well-known encodings:
//! - the stack channels `harvest-foxglove-mapping` reads become its mapped topics (protobuf,
//!   schemas in the file): the camera as JPEG `/camera/image` (the live view's size unless asked
//!   otherwise) with calibration and annotations, the 3D scene, transforms, joints, pressures, the event log. Every message is
//!   mapped (no viewing-rate limit); the mapped channels a recent recording already holds are
//!   left out, since they are made again at full rate.
//! - every catalogue message also keeps its JSON view on its own topic (`message_encoding =
//!   json`, schema inferred), so every field stays plottable; frames' JSON views are their
//!   metadata only.
//! - channels already in an encoding Foxglove reads (the recorder's `recorder/events` JSON, the
//!   continuous record's `camera/video` H.264) are copied as they are.
//!
//! Stamps are converted to UTC with the recording's `harvest.clock` record when it has one; the
//! camera's mounting comes from its `harvest.calibration` record.

use crate::json_schema::infer_schema;
use crate::time_base::FileTimeBase;
use harvest_foxglove_mapping::mounting_files::robot_from_camera_text;
use harvest_foxglove_mapping::topics::{self, MappedSink, Topic, encode_into};
use harvest_foxglove_mapping::{EncodedMapper, ImageSettings, MapError, Mounting, TimeBase};
use mcap::records::{MessageHeader, Metadata};
use mcap::{WriteOptions, Writer};
use serde_json::Value;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// The mcap writer and its channels (the sink of the mapping).
struct Output {
    writer: Writer<BufWriter<File>>,
    /// Output topic -> channel id.
    channels: BTreeMap<String, u16>,
    sequences: BTreeMap<u16, u32>,
    buffer: Vec<u8>,
    messages_written: u64,
}

fn mcap_text(error: mcap::McapError) -> String {
    crate::mcap_error::mcap_error_text(&error)
}

impl Output {
    fn write(
        &mut self,
        channel_id: u16,
        log_time_ns: u64,
        publish_time_ns: u64,
    ) -> Result<(), String> {
        let sequence = self.sequences.entry(channel_id).or_insert(0);
        *sequence = sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id,
            sequence: *sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        self.writer
            .write_to_known_channel(&header, &self.buffer)
            .map_err(mcap_text)?;
        self.messages_written += 1;
        Ok(())
    }
}

impl MappedSink for Output {
    type Error = String;

    fn write<M: foxglove::Encode>(
        &mut self,
        topic: Topic<M>,
        log_time_ns: u64,
        message: &M,
    ) -> Result<(), String> {
        let id = match self.channels.get(topic.name) {
            Some(id) => *id,
            None => {
                let description = topic.describe();
                let schema_id = match &description.schema {
                    Some(schema) => self
                        .writer
                        .add_schema(&schema.name, &schema.encoding, &schema.data)
                        .map_err(mcap_text)?,
                    None => 0,
                };
                let metadata = BTreeMap::from([(
                    "description".to_owned(),
                    description.description.to_owned(),
                )]);
                let id = self
                    .writer
                    .add_channel(
                        schema_id,
                        topic.name,
                        &description.message_encoding,
                        &metadata,
                    )
                    .map_err(mcap_text)?;
                self.channels.insert(topic.name.to_owned(), id);
                id
            }
        };
        encode_into(message, &mut self.buffer).map_err(|error| error.to_string())?;
        Output::write(self, id, log_time_ns, log_time_ns)
    }
}

/// A Foxglove-readable MCAP being written.
pub struct FoxgloveWriter {
    output: Output,
    /// How the input's log times read (learnt from its `harvest.clock` record).
    time: FileTimeBase,
    mounting: Mounting,
    /// Made on the first mapped message, once the clock and calibration records are known.
    mapper: Option<EncodedMapper>,
    image: ImageSettings,
}

impl FoxgloveWriter {
    /// Creates `path`; camera images are mapped with `image`.
    pub fn create(path: &Path, image: ImageSettings) -> Result<Self, String> {
        let file = File::create(path).map_err(|error| format!("{}: {error}", path.display()))?;
        let options = WriteOptions::new()
            .profile("")
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .compression_threads(0)
            .chunk_size(Some(8 << 20));
        let writer = Writer::with_options(BufWriter::with_capacity(1 << 20, file), options)
            .map_err(mcap_text)?;
        Ok(Self {
            output: Output {
                writer,
                channels: BTreeMap::new(),
                sequences: BTreeMap::new(),
                buffer: Vec::new(),
                messages_written: 0,
            },
            time: FileTimeBase::default(),
            mounting: Mounting::default(),
            mapper: None,
            image,
        })
    }

    pub fn messages_written(&self) -> u64 {
        self.output.messages_written
    }

    /// Takes in a metadata record of the input (clock, calibration) and copies it.
    pub fn write_metadata(&mut self, metadata: &Metadata) -> Result<(), String> {
        self.time.observe(metadata);
        if metadata.name == crate::metadata::CALIBRATION
            && self.mounting.robot_from_camera.is_none()
            && let Some(text) = metadata.metadata.get("text")
        {
            match robot_from_camera_text(text, "the recording's harvest.calibration record") {
                Ok(transform) => self.mounting.robot_from_camera = Some(transform),
                Err(error) => {
                    tracing::warn!(%error, "the export leaves the camera unplaced in the 3D view")
                }
            }
        }
        self.output
            .writer
            .write_metadata(metadata)
            .map_err(mcap_text)
    }

    /// An input log or publish time on the output's UTC time base (unchanged when the input
    /// has no clock record).
    fn stamp(&self, file_time_ns: u64) -> u64 {
        self.time
            .realtime_pair()
            .map(|pair| pair.to_realtime_ns(self.time.stack_ns(file_time_ns)))
            .unwrap_or(file_time_ns)
    }

    /// True for the mapped channels a recording already holds (left out: made again).
    pub fn is_mapped_output(topic: &str, message_encoding: &str) -> bool {
        message_encoding == "protobuf" && topics::all().iter().any(|mapped| mapped.name == topic)
    }

    /// Writes a message's JSON view on its own topic, with a schema inferred from it.
    pub fn write_json(
        &mut self,
        topic: &str,
        type_name: &str,
        log_time_ns: u64,
        publish_time_ns: u64,
        value: &Value,
    ) -> Result<(), String> {
        let id = match self.output.channels.get(topic) {
            Some(id) => *id,
            None => {
                let schema = infer_schema(type_name, value).to_string();
                let schema_id = self
                    .output
                    .writer
                    .add_schema(type_name, "jsonschema", schema.as_bytes())
                    .map_err(mcap_text)?;
                let id = self
                    .output
                    .writer
                    .add_channel(schema_id, topic, "json", &BTreeMap::new())
                    .map_err(mcap_text)?;
                self.output.channels.insert(topic.to_owned(), id);
                id
            }
        };
        self.output.buffer.clear();
        serde_json::to_writer(&mut self.output.buffer, value).map_err(|error| error.to_string())?;
        let (log_time_ns, publish_time_ns) = (self.stamp(log_time_ns), self.stamp(publish_time_ns));
        self.output.write(id, log_time_ns, publish_time_ns)
    }

    /// Copies a message of a channel Foxglove reads as it is (JSON or protobuf with its schema:
    /// the recorder's events, the camera video), its log and publish times on the output's UTC
    /// time base.
    pub fn write_as_is(
        &mut self,
        channel: &mcap::Channel<'_>,
        log_time_ns: u64,
        publish_time_ns: u64,
        data: &[u8],
    ) -> Result<(), String> {
        let id = match self.output.channels.get(&channel.topic) {
            Some(id) => *id,
            None => {
                let schema_id = match &channel.schema {
                    Some(schema) => self
                        .output
                        .writer
                        .add_schema(&schema.name, &schema.encoding, &schema.data)
                        .map_err(mcap_text)?,
                    None => 0,
                };
                let id = self
                    .output
                    .writer
                    .add_channel(
                        schema_id,
                        &channel.topic,
                        &channel.message_encoding,
                        &channel.metadata,
                    )
                    .map_err(mcap_text)?;
                self.output.channels.insert(channel.topic.clone(), id);
                id
            }
        };
        self.output.buffer.clear();
        self.output.buffer.extend_from_slice(data);
        let (log_time_ns, publish_time_ns) = (self.stamp(log_time_ns), self.stamp(publish_time_ns));
        self.output.write(id, log_time_ns, publish_time_ns)
    }

    /// Maps one recorded message of a stack channel (encoded with this build's payload
    /// version). Returns `false` when the mapping does not read that channel.
    pub fn write_mapped(
        &mut self,
        topic: &str,
        bytes: &[u8],
        log_time_ns: u64,
    ) -> Result<bool, MapError<String>> {
        let time = match self.time.realtime_pair() {
            Some(pair) => TimeBase::realtime(pair.monotonic_ns, pair.realtime_ns),
            None => TimeBase::MONOTONIC,
        };
        let log_time_ns = self.time.stack_ns(log_time_ns);
        let mapper = self
            .mapper
            .get_or_insert_with(|| EncodedMapper::new(time, self.image, self.mounting));
        mapper.map(topic, bytes, log_time_ns, &mut self.output)
    }

    pub fn finish(mut self) -> Result<(), String> {
        self.output.writer.finish().map_err(mcap_text)?;
        Ok(())
    }
}
