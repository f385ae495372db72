//! The MCAP metadata records of a recording: what was recorded, by which software, under which
//! launch configuration, calibration and scenario, and how its stamps map to wall-clock time.
//!
//! Every segment file starts with `harvest.recording` and `harvest.clock`, then the session
//! records (`harvest.launch`, `harvest.calibration`, `harvest.scenario`, `harvest.notes`, each
//! only when given); the last segment ends with `harvest.drops`, a segment closed because the
//! disk filled up with `harvest.disk_full`; a segment whose events channel has messages ends
//! with `harvest.events` (their count by kind).

use crate::wall_clock::{ClockPair, format_utc_iso};
use mcap::records::Metadata;
use std::collections::BTreeMap;
use std::path::Path;

/// Name of the record describing the recording session and this segment.
pub const RECORDING: &str = "harvest.recording";
/// Name of the record holding one (monotonic, realtime) clock pair.
pub const CLOCK: &str = "harvest.clock";
/// Launch file given to the recorder.
pub const LAUNCH: &str = "harvest.launch";
/// Calibration file given to the recorder.
pub const CALIBRATION: &str = "harvest.calibration";
/// Scenario given to the recorder.
pub const SCENARIO: &str = "harvest.scenario";
/// Free-form `key=value` notes.
pub const NOTES: &str = "harvest.notes";
/// Per-channel receive and drop counts, written when the recording ends.
pub const DROPS: &str = "harvest.drops";
/// Written by `harvest rec recover` into the file it rewrote.
pub const RECOVERY: &str = "harvest.recovery";
/// Ends a segment the recorder closed because its disk was full (free and needed bytes).
pub const DISK_FULL: &str = "harvest.disk_full";

/// Events of the segment or clip (triggers and marks on `recorder/events`), counted by kind.
pub const EVENTS: &str = "harvest.events";

/// Describes a flight-recorder clip: its triggers, window and what the ring covered.
pub const CLIP: &str = "harvest.clip";

/// Version of the software that writes recordings (the workspace version).
pub const SOFTWARE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Builds a metadata record from key/value pairs.
pub fn record<K: Into<String>, V: Into<String>>(
    name: &str,
    entries: impl IntoIterator<Item = (K, V)>,
) -> Metadata {
    Metadata {
        name: name.to_owned(),
        metadata: entries
            .into_iter()
            .map(|(k, v)| (k.into(), v.into()))
            .collect(),
    }
}

/// Key of the `harvest.clock` record holding the offset added to stack-clock stamps to make
/// the file's log and publish times (see [`crate::time_base`]).
pub const LOG_TIME_OFFSET_NS: &str = "log_time_offset_ns";

/// The `harvest.clock` record of a clock pair; `log_time_offset_ns` when the file's log and
/// publish times are wall-clock time (stack stamp + this offset).
pub fn clock_record(pair: ClockPair, log_time_offset_ns: Option<i64>) -> Metadata {
    let mut entries = vec![
        ("monotonic_ns", pair.monotonic_ns.to_string()),
        ("realtime_ns", pair.realtime_ns.to_string()),
        ("realtime_utc", format_utc_iso(pair.realtime_ns)),
    ];
    match log_time_offset_ns {
        Some(offset) => {
            entries.push((LOG_TIME_OFFSET_NS, offset.to_string()));
            entries.push((
                "meaning",
                "log_time and publish_time are Unix-epoch ns (UTC) = CLOCK_MONOTONIC stamp of \
the recording host + log_time_offset_ns; stamps inside payloads stay CLOCK_MONOTONIC ns"
                    .to_owned(),
            ));
        }
        None => entries.push((
            "meaning",
            "log_time and publish_time are CLOCK_MONOTONIC ns of the recording host; \
realtime_ns = stamp + (realtime_ns - monotonic_ns) of this record"
                .to_owned(),
        )),
    }
    record(CLOCK, entries)
}

/// The log-time offset of a `harvest.clock` record (`None`: stack-clock log times).
pub fn parse_log_time_offset(metadata: &Metadata) -> Option<i64> {
    if metadata.name != CLOCK {
        return None;
    }
    metadata.metadata.get(LOG_TIME_OFFSET_NS)?.parse().ok()
}

/// Reads a clock pair back from a `harvest.clock` record.
pub fn parse_clock(metadata: &Metadata) -> Option<ClockPair> {
    if metadata.name != CLOCK {
        return None;
    }
    Some(ClockPair {
        monotonic_ns: metadata.metadata.get("monotonic_ns")?.parse().ok()?,
        realtime_ns: metadata.metadata.get("realtime_ns")?.parse().ok()?,
    })
}

/// A record holding a file's path and text (`text` empty and `error` set if it is unreadable).
pub fn file_record(name: &str, path: &Path) -> Metadata {
    let mut entries = BTreeMap::from([("path".to_owned(), path.display().to_string())]);
    match std::fs::read_to_string(path) {
        Ok(text) => {
            entries.insert("text".to_owned(), text);
        }
        Err(error) => {
            tracing::warn!(path = %path.display(), %error, "{name}: cannot read file; recording its path only");
            entries.insert("error".to_owned(), error.to_string());
        }
    }
    Metadata {
        name: name.to_owned(),
        metadata: entries,
    }
}

/// The scenario record: the given text, plus the file's content when it names a readable file.
pub fn scenario_record(scenario: &str) -> Metadata {
    let mut entries = BTreeMap::from([("scenario".to_owned(), scenario.to_owned())]);
    let path = Path::new(scenario);
    if path.is_file() {
        match std::fs::read_to_string(path) {
            Ok(text) => {
                entries.insert("text".to_owned(), text);
            }
            Err(error) => {
                entries.insert("error".to_owned(), error.to_string());
            }
        }
    }
    Metadata {
        name: SCENARIO.to_owned(),
        metadata: entries,
    }
}

/// Splits `key=value` notes; an entry without `=` becomes a key with an empty value.
pub fn notes_record(notes: &[String]) -> Metadata {
    record(
        NOTES,
        notes.iter().map(|note| match note.split_once('=') {
            Some((key, value)) => (key.trim().to_owned(), value.to_owned()),
            None => (note.trim().to_owned(), String::new()),
        }),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clock_record_round_trips() {
        let pair = ClockPair {
            monotonic_ns: 123,
            realtime_ns: 1_700_000_000_000_000_000,
        };
        let metadata = clock_record(pair, None);
        assert_eq!(parse_clock(&metadata), Some(pair));
        assert_eq!(
            metadata.metadata["realtime_utc"],
            "2023-11-14T22:13:20.000Z"
        );
        assert_eq!(parse_clock(&record(NOTES, [("a", "b")])), None);
        assert_eq!(parse_log_time_offset(&metadata), None);
        let wall = clock_record(pair, Some(-5));
        assert_eq!(parse_clock(&wall), Some(pair));
        assert_eq!(parse_log_time_offset(&wall), Some(-5));
    }

    #[test]
    fn notes_and_unreadable_files() {
        let notes = notes_record(&["operator=ana".into(), "row 7".into(), "k=a=b".into()]);
        assert_eq!(notes.metadata["operator"], "ana");
        assert_eq!(notes.metadata["row 7"], "");
        assert_eq!(notes.metadata["k"], "a=b");
        let missing = file_record(LAUNCH, Path::new("/nonexistent/launch.toml"));
        assert!(missing.metadata.contains_key("error"));
        assert!(!missing.metadata.contains_key("text"));
        let scenario = scenario_record("dense-canopy");
        assert_eq!(scenario.metadata["scenario"], "dense-canopy");
    }
}
