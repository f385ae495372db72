//! `harvest rec cat`: recorded messages as JSON lines, decoded with this build's payload types.
//!
//! Each line: `{"topic", "schema", "log_time_ns", "publish_time_ns", "t_s", "sequence",
//! "message"}` where `t_s` is seconds since the recording's first message and `message` is the
//! payload's `to_json` view. Messages of unknown schemas or of another payload version are
//! skipped with one warning per topic.

use crate::camera_record::camera_json;
use crate::foxglove_export::FoxgloveWriter;
use crate::payload_codec::{JsonDecoder, SchemaMatch, json_decoder};
use crate::recorded_events::EVENTS_TOPIC;
use crate::recording_file::ReadError;
use crate::scan::{ScanEnd, ScanItem, ScanOptions, scan_file};
use crate::time_window::{absolute_window, recording_start_ns};
use crate::topic_filter::TopicFilter;
use std::collections::BTreeMap;
use std::io::Write;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Duration;

/// What to print.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CatOptions {
    /// Topic globs (all topics when empty).
    pub topics: Vec<String>,
    /// Skip messages before this offset from the first message.
    pub start: Option<Duration>,
    /// Stop after this offset from the first message.
    pub end: Option<Duration>,
}

/// What `rec cat` printed and skipped.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct CatReport {
    pub printed: u64,
    /// Topic -> (messages skipped, why).
    pub undecodable: BTreeMap<String, (u64, String)>,
    /// Topic -> messages of the channels mapped for Foxglove (protobuf views made from the raw
    /// channels by the recorder), not printed.
    pub mapped_views: BTreeMap<String, u64>,
    /// Why the file could not be read to its end, if so.
    pub incomplete: Option<String>,
    /// The output was closed (e.g. piped into `head`).
    pub output_closed: bool,
}

/// `rec cat` failed.
#[derive(Debug, thiserror::Error)]
pub enum CatError {
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Writing the output failed (other than its reader going away).
    #[error("writing the output failed: {0}")]
    Output(std::io::Error),
}

/// Prints the selected messages of `path` to `out` as JSON lines.
pub fn cat(path: &Path, options: &CatOptions, out: &mut dyn Write) -> Result<CatReport, CatError> {
    let filter = TopicFilter::patterns(&options.topics, &[]);
    let start_ns = recording_start_ns(path)?.unwrap_or(0);
    let (from_ns, to_ns) = absolute_window(start_ns, options.start, options.end);
    let mut decoders: BTreeMap<u16, Option<Box<dyn JsonDecoder>>> = BTreeMap::new();
    let mut report = CatReport::default();
    let mut output_error = None;
    let mut line = Vec::new();
    let outcome = scan_file(
        path,
        ScanOptions {
            log_time_window: Some((from_ns, to_ns)),
        },
        |item| {
            let ScanItem::Message(message) = item else {
                return ControlFlow::Continue(());
            };
            if message.log_time < from_ns || message.log_time > to_ns {
                return ControlFlow::Continue(());
            }
            let channel = &message.channel;
            if !filter.matches_topic(&channel.topic) {
                return ControlFlow::Continue(());
            }
            if FoxgloveWriter::is_mapped_output(&channel.topic, &channel.message_encoding) {
                *report
                    .mapped_views
                    .entry(channel.topic.clone())
                    .or_insert(0) += 1;
                return ControlFlow::Continue(());
            }
            let schema = channel
                .schema
                .as_ref()
                .map(|schema| schema.name.as_str())
                .unwrap_or("");
            // The recorder's events channel (JSON) prints as it is.
            let json_value = (channel.topic == EVENTS_TOPIC && channel.message_encoding == "json")
                .then(|| serde_json::from_slice::<serde_json::Value>(message.data).ok())
                .flatten()
                // The continuous record's camera video and depth: a summary of each.
                .or_else(|| camera_json(&channel.topic, message.data));
            let decoder = decoders.entry(channel.id).or_insert_with(|| match &json_value {
            Some(_) => None,
            None => match json_decoder(schema) {
            SchemaMatch::Known(decoder) => Some(decoder),
            other => {
                let reason = other.problem(schema).unwrap_or_default();
                tracing::warn!(topic = %channel.topic, %reason, "skipping the topic's messages");
                report.undecodable.insert(channel.topic.clone(), (0, reason));
                None
            }
        }});
            let decoded = match (json_value, decoder.as_mut()) {
                (Some(value), _) => Ok(value),
                (None, Some(decoder)) => decoder
                    .to_json(message.data)
                    .map_err(|error| error.to_string()),
                (None, None) => {
                    if let Some((count, _)) = report.undecodable.get_mut(&channel.topic) {
                        *count += 1;
                    }
                    return ControlFlow::Continue(());
                }
            };
            let value = match decoded {
                Ok(value) => value,
                Err(error) => {
                    let entry = report
                        .undecodable
                        .entry(channel.topic.clone())
                        .or_insert_with(|| (0, format!("undecodable message: {error}")));
                    entry.0 += 1;
                    return ControlFlow::Continue(());
                }
            };
            let record = serde_json::json!({
                "topic": channel.topic,
                "schema": schema,
                "log_time_ns": message.log_time,
                "publish_time_ns": message.publish_time,
                "t_s": message.log_time.saturating_sub(start_ns) as f64 * 1e-9,
                "sequence": message.sequence,
                "message": value,
            });
            line.clear();
            if serde_json::to_writer(&mut line, &record).is_ok() {
                line.push(b'\n');
                if let Err(error) = out.write_all(&line) {
                    output_error = Some(error);
                    return ControlFlow::Break(());
                }
                report.printed += 1;
            }
            ControlFlow::Continue(())
        },
    )?;
    if let Err(error) = out.flush() {
        output_error.get_or_insert(error);
    }
    match output_error {
        Some(error) if error.kind() == std::io::ErrorKind::BrokenPipe => {
            report.output_closed = true
        }
        Some(error) => return Err(CatError::Output(error)),
        None => {}
    }
    if let ScanEnd::Truncated { reason, .. } = outcome.end {
        report.incomplete = Some(reason);
    }
    for damaged in &outcome.damaged_chunks {
        tracing::warn!(offset = damaged.offset, reason = %damaged.reason, "damaged chunk skipped");
    }
    Ok(report)
}
