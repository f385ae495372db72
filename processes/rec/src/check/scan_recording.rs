//! One pass over a recording's segments for the check: every message in order, damaged chunks
//! skipped with a warning.

use std::ops::ControlFlow;
use std::path::PathBuf;

use harvest_recording::scan::{ScanItem, ScanOptions, ScannedMessage, scan_file};

use crate::check::report::CheckError;

/// Calls `on_message` with every message of `files` (segments of one recording, in order);
/// stops at its first error.
pub fn scan(
    files: &[PathBuf],
    mut on_message: impl FnMut(&ScannedMessage<'_>) -> Result<(), CheckError>,
) -> Result<(), CheckError> {
    for file in files {
        let mut failure = None;
        let outcome = scan_file(file, ScanOptions::default(), |item| {
            if let ScanItem::Message(message) = item
                && let Err(error) = on_message(&message)
            {
                failure = Some(error);
                return ControlFlow::Break(());
            }
            ControlFlow::Continue(())
        })
        .map_err(|error| CheckError::Read {
            file: file.clone(),
            message: error.to_string(),
        })?;
        if let Some(error) = failure {
            return Err(error);
        }
        for damaged in &outcome.damaged_chunks {
            tracing::warn!(file = %file.display(), offset = damaged.offset, reason = %damaged.reason, "damaged chunk skipped");
        }
    }
    Ok(())
}

/// A recorded message of `topic` that does not decode as this build's type.
pub fn undecodable(topic: &str, log_time_ns: u64) -> CheckError {
    CheckError::Undecodable {
        topic: topic.to_owned(),
        log_time_ns,
    }
}
