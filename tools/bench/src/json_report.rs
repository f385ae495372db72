//! A benchmark's report written as pretty JSON (`--json FILE`).

use serde::Serialize;
use std::path::Path;

/// Writes `report` to `path` as pretty JSON.
pub fn write_json_report<T: Serialize>(path: &Path, report: &T) -> std::io::Result<()> {
    let text = serde_json::to_string_pretty(report).map_err(std::io::Error::other)?;
    std::fs::write(path, text)
}
