//! `harvest rec export`: camera frames to PNG (`--png DIR`) and the whole recording to a
//! Foxglove-readable MCAP (`--foxglove OUT.mcap`: the mapped channels of
//! `harvest-foxglove-mapping` at full rate, plus each message's JSON view; see
//! [`crate::foxglove_export`]), in one pass over the file.

use crate::foxglove_export::FoxgloveWriter;
use crate::payload_codec::{JsonDecoder, SchemaMatch, json_decoder, zeroed_box};
use crate::png_export::PngWriter;
use crate::recording_file::ReadError;
use crate::scan::{ScanEnd, ScanItem, ScanOptions, scan_file};
use crate::schema::schema_name;
use crate::time_window::{absolute_window, recording_start_ns};
use crate::topic_filter::TopicFilter;
use harvest_foxglove_mapping::ImageSettings;
use harvest_foxglove_mapping::encoded::mapped_channels;
use harvest_ipc::Payload;
use harvest_ipc::payloads::RgbdFrame;
use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// What to export.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ExportOptions {
    /// Directory for PNG frames.
    pub png_dir: Option<PathBuf>,
    /// Output file for the Foxglove export.
    pub foxglove: Option<PathBuf>,
    /// How camera images are encoded in the Foxglove export: every frame, at the live view's
    /// size and quality by default (`ImageSettings::VIEWING`).
    pub foxglove_image: ImageSettings,
    /// Topic globs (all topics when empty).
    pub topics: Vec<String>,
    /// Offsets from the recording's first message.
    pub start: Option<Duration>,
    pub end: Option<Duration>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            png_dir: None,
            foxglove: None,
            foxglove_image: ImageSettings::VIEWING,
            topics: Vec::new(),
            start: None,
            end: None,
        }
    }
}

/// What was exported.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ExportReport {
    pub png_frames: u64,
    pub foxglove_messages: u64,
    /// Topic -> (messages skipped, why).
    pub skipped: BTreeMap<String, (u64, String)>,
    /// Why the input could not be read to its end, if so.
    pub incomplete: Option<String>,
}

/// `rec export` failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// Neither `--png` nor `--foxglove` was given.
    #[error("nothing to export: give --png DIR, --foxglove OUT.mcap and/or --ros2 OUT")]
    NothingRequested,
    /// The output would overwrite the input.
    #[error("the export {0} would overwrite its input")]
    SameFile(PathBuf),
    /// The image settings are unusable.
    #[error("rec export: {0}")]
    InvalidOption(String),
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Writing an output failed.
    #[error("export output: {0}")]
    Output(String),
}

enum TopicDecoder {
    Frame,
    /// The JSON view; `mapped`: the channel is also mapped for Foxglove.
    Json {
        decoder: Box<dyn JsonDecoder>,
        mapped: bool,
    },
    /// A mapped channel the input already holds (made again at full rate).
    MappedOutput,
    /// A channel in an encoding Foxglove reads (JSON, protobuf: the recorder's events, the
    /// camera video), copied as it is.
    AsIs,
    Skip,
}

/// True for a recorded channel that is not a catalogue payload but already in an encoding
/// Foxglove displays (the recorder's `recorder/events` JSON, the `camera/video` protobuf).
fn readable_as_is(channel: &mcap::Channel<'_>) -> bool {
    matches!(channel.message_encoding.as_str(), "json" | "protobuf")
        && channel
            .schema
            .as_ref()
            .is_some_and(|schema| matches!(schema.encoding.as_str(), "jsonschema" | "protobuf"))
}

/// Exports `path` as `options` asks.
pub fn export(path: &Path, options: &ExportOptions) -> Result<ExportReport, ExportError> {
    if options.png_dir.is_none() && options.foxglove.is_none() {
        return Err(ExportError::NothingRequested);
    }
    if let Some(out) = &options.foxglove
        && crate::recover::same_file(path, out)
    {
        return Err(ExportError::SameFile(out.clone()));
    }
    if let Some(problem) = options.foxglove_image.problem() {
        return Err(ExportError::InvalidOption(problem));
    }
    // Mapped stack channels, by schema name of the payload version this build maps.
    let mapped_schemas: Vec<String> = mapped_channels()
        .iter()
        .map(|(_, type_name, version)| schema_name(type_name, *version))
        .collect();
    let filter = TopicFilter::patterns(&options.topics, &[]);
    let start_ns = recording_start_ns(path)?.unwrap_or(0);
    let (from_ns, to_ns) = absolute_window(start_ns, options.start, options.end);
    let mut png = match &options.png_dir {
        Some(dir) => Some(
            PngWriter::create(dir)
                .map_err(|error| ExportError::Output(format!("{}: {error}", dir.display())))?,
        ),
        None => None,
    };
    let mut foxglove = match &options.foxglove {
        Some(out) => {
            Some(FoxgloveWriter::create(out, options.foxglove_image).map_err(ExportError::Output)?)
        }
        None => None,
    };
    let frame_schema = schema_name(RgbdFrame::TYPE_NAME, RgbdFrame::VERSION);
    let mut frame = zeroed_box::<RgbdFrame>();
    let mut decoders: BTreeMap<u16, TopicDecoder> = BTreeMap::new();
    let mut report = ExportReport::default();
    let mut failure: Option<String> = None;
    let outcome = scan_file(
        path,
        ScanOptions {
            log_time_window: Some((from_ns, to_ns)),
        },
        |item| {
            let result = match item {
                ScanItem::Metadata(record) => match foxglove.as_mut() {
                    Some(writer) => writer.write_metadata(record),
                    None => Ok(()),
                },
                ScanItem::Message(message) => {
                    let channel = &message.channel;
                    if message.log_time < from_ns
                        || message.log_time > to_ns
                        || !filter.matches_topic(&channel.topic)
                    {
                        return ControlFlow::Continue(());
                    }
                    let schema = channel
                        .schema
                        .as_ref()
                        .map(|schema| schema.name.as_str())
                        .unwrap_or("");
                    let decoder = decoders.entry(channel.id).or_insert_with(|| {
                        if schema == frame_schema {
                            return TopicDecoder::Frame;
                        }
                        if FoxgloveWriter::is_mapped_output(
                            &channel.topic,
                            &channel.message_encoding,
                        ) {
                            return TopicDecoder::MappedOutput;
                        }
                        if readable_as_is(channel) {
                            return if foxglove.is_some() {
                                TopicDecoder::AsIs
                            } else {
                                TopicDecoder::Skip
                            };
                        }
                        match json_decoder(schema) {
                            SchemaMatch::Known(decoder) if foxglove.is_some() => {
                                TopicDecoder::Json {
                                    decoder,
                                    mapped: mapped_schemas.iter().any(|name| name == schema),
                                }
                            }
                            SchemaMatch::Known(_) => TopicDecoder::Skip,
                            other => {
                                let reason = other.problem(schema).unwrap_or_default();
                                tracing::warn!(topic = %channel.topic, %reason, "not exported");
                                report.skipped.insert(channel.topic.clone(), (0, reason));
                                TopicDecoder::Skip
                            }
                        }
                    });
                    let (log_time, publish_time) = (message.log_time, message.publish_time);
                    match decoder {
                        TopicDecoder::MappedOutput => Ok(()),
                        TopicDecoder::AsIs => match foxglove.as_mut() {
                            Some(writer) => {
                                writer.write_as_is(channel, log_time, publish_time, message.data)
                            }
                            None => Ok(()),
                        },
                        TopicDecoder::Skip => {
                            if let Some((count, _)) = report.skipped.get_mut(&channel.topic) {
                                *count += 1;
                            }
                            Ok(())
                        }
                        TopicDecoder::Json { decoder, mapped } => {
                            match decoder.to_json(message.data) {
                                Ok(value) => match foxglove.as_mut() {
                                    Some(writer) => writer
                                        .write_json(
                                            &channel.topic,
                                            decoder.type_name(),
                                            log_time,
                                            publish_time,
                                            &value,
                                        )
                                        .and_then(|()| {
                                            if *mapped {
                                                writer
                                                    .write_mapped(
                                                        &channel.topic,
                                                        message.data,
                                                        log_time,
                                                    )
                                                    .map(|_| ())
                                                    .map_err(|error| error.to_string())
                                            } else {
                                                Ok(())
                                            }
                                        }),
                                    None => Ok(()),
                                },
                                Err(error) => {
                                    report
                                        .skipped
                                        .entry(channel.topic.clone())
                                        .or_insert_with(|| (0, error.to_string()))
                                        .0 += 1;
                                    Ok(())
                                }
                            }
                        }
                        TopicDecoder::Frame => {
                            match RgbdFrame::decode_into(message.data, &mut frame) {
                                Ok(()) => {
                                    let mut result = Ok(());
                                    if let Some(writer) = png.as_mut() {
                                        result = writer.write(&channel.topic, log_time, &frame);
                                    }
                                    if let (Ok(()), Some(writer)) = (&result, foxglove.as_mut()) {
                                        result = writer
                                            .write_json(
                                                &channel.topic,
                                                RgbdFrame::TYPE_NAME,
                                                log_time,
                                                publish_time,
                                                &frame.to_json(),
                                            )
                                            .and_then(|()| {
                                                writer
                                                    .write_mapped(
                                                        &channel.topic,
                                                        message.data,
                                                        log_time,
                                                    )
                                                    .map(|_| ())
                                                    .map_err(|error| error.to_string())
                                            });
                                    }
                                    result
                                }
                                Err(error) => {
                                    report
                                        .skipped
                                        .entry(channel.topic.clone())
                                        .or_insert_with(|| (0, error.to_string()))
                                        .0 += 1;
                                    Ok(())
                                }
                            }
                        }
                    }
                }
                ScanItem::Chunk(_) | ScanItem::DamagedChunk(_) => Ok(()),
            };
            match result {
                Ok(()) => ControlFlow::Continue(()),
                Err(error) => {
                    failure = Some(error);
                    ControlFlow::Break(())
                }
            }
        },
    )?;
    if let Some(error) = failure {
        return Err(ExportError::Output(error));
    }
    if let Some(writer) = png {
        report.png_frames = writer.frames_written;
        writer.finish().map_err(ExportError::Output)?;
    }
    if let Some(writer) = foxglove {
        report.foxglove_messages = writer.messages_written();
        writer.finish().map_err(ExportError::Output)?;
    }
    if let ScanEnd::Truncated { reason, .. } = outcome.end {
        report.incomplete = Some(reason);
    }
    Ok(report)
}
