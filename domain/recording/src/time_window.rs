//! Time selections of the recording tools, given relative to the recording's first message.

use crate::recording_file::{ReadError, read_summary};
use crate::scan::{ScanItem, ScanOptions, scan_file};
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Duration;

/// `log_time` of the recording's first message: from the summary statistics when present,
/// else from the first chunk or message in the file. `None` for a recording without messages.
pub fn recording_start_ns(path: &Path) -> Result<Option<u64>, ReadError> {
    if let Ok(Some(summary)) = read_summary(path)
        && let Some(stats) = summary
            .stats
            .as_ref()
            .filter(|stats| stats.message_count > 0)
    {
        return Ok(Some(stats.message_start_time));
    }
    let mut start = None;
    scan_file(path, ScanOptions::default(), |item| match item {
        ScanItem::Chunk(chunk) if chunk.uncompressed_bytes > 0 && chunk.message_start_time > 0 => {
            start = Some(chunk.message_start_time);
            ControlFlow::Break(())
        }
        ScanItem::Message(message) => {
            start = Some(message.log_time);
            ControlFlow::Break(())
        }
        _ => ControlFlow::Continue(()),
    })?;
    Ok(start)
}

/// An inclusive `log_time` window from offsets after `start_ns`: `[start_ns + from, start_ns +
/// to]` (`to` unbounded when `None`).
pub fn absolute_window(start_ns: u64, from: Option<Duration>, to: Option<Duration>) -> (u64, u64) {
    let nanos = |duration: Duration| u64::try_from(duration.as_nanos()).unwrap_or(u64::MAX);
    let begin = start_ns.saturating_add(from.map(nanos).unwrap_or(0));
    let end = to
        .map(|to| start_ns.saturating_add(nanos(to)))
        .unwrap_or(u64::MAX);
    (begin, end)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_are_relative_to_the_start() {
        assert_eq!(absolute_window(1_000, None, None), (1_000, u64::MAX));
        assert_eq!(
            absolute_window(
                1_000,
                Some(Duration::from_micros(1)),
                Some(Duration::from_micros(3))
            ),
            (2_000, 4_000)
        );
    }
}
