//! `harvest rec clips DIR`: the flight-recorder clips of a directory with their triggers, time,
//! length and size, read from each clip's `harvest.clip` record through the file's summary (the
//! clip's data is not read).

use crate::metadata;
use crate::recording_file::{read_indexed_metadata, read_summary};
use crate::units::format_bytes;
use std::path::{Path, PathBuf};

/// One clip.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipInfo {
    pub path: PathBuf,
    pub size_bytes: u64,
    /// Trigger kinds, in order (`mark`, `failed_attempt`, ...).
    pub triggers: Vec<String>,
    /// The triggers' texts.
    pub texts: String,
    pub first_trigger_utc: String,
    /// Length of the window, s.
    pub window_s: f64,
    /// Length the ring covered, s (less than the window when it held less).
    pub covered_s: f64,
    pub messages: u64,
    /// Why the clip could not be read (the other fields are then empty).
    pub problem: Option<String>,
}

/// The `*.mcap` files of `dir` (clips in progress, `.mcap.partial`, are left out), by name
/// (which starts with the trigger's UTC time).
pub fn list_clips(dir: &Path) -> std::io::Result<Vec<ClipInfo>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(Result::ok)
        .map(|entry| entry.path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "mcap") && path.is_file())
        .collect();
    paths.sort();
    Ok(paths.into_iter().map(|path| clip_info(&path)).collect())
}

/// Reads one clip's description.
pub fn clip_info(path: &Path) -> ClipInfo {
    let mut info = ClipInfo {
        path: path.to_path_buf(),
        size_bytes: std::fs::metadata(path).map_or(0, |meta| meta.len()),
        triggers: Vec::new(),
        texts: String::new(),
        first_trigger_utc: String::new(),
        window_s: 0.0,
        covered_s: 0.0,
        messages: 0,
        problem: None,
    };
    let record = match read_summary(path) {
        Ok(Some(summary)) => read_indexed_metadata(path, &summary.metadata_indexes)
            .map_err(|problem| format!("metadata unreadable: {problem}"))
            .and_then(|records| {
                records
                    .into_iter()
                    .find(|record| record.name == metadata::CLIP)
                    .ok_or_else(|| "no harvest.clip record (not a clip)".to_owned())
            }),
        Ok(None) => Err("no summary: not finished".to_owned()),
        Err(problem) => Err(problem),
    };
    match record {
        Ok(record) => {
            let get = |key: &str| record.metadata.get(key).cloned().unwrap_or_default();
            info.triggers = get("triggers")
                .split(',')
                .filter(|kind| !kind.is_empty())
                .map(str::to_owned)
                .collect();
            info.texts = get("texts");
            info.first_trigger_utc = get("first_trigger_utc");
            info.window_s = get("window_s").parse().unwrap_or(0.0);
            info.covered_s = get("covered_s").parse().unwrap_or(0.0);
            info.messages = get("messages").parse().unwrap_or(0);
        }
        Err(problem) => info.problem = Some(problem),
    }
    info
}

/// The listing as `rec clips` prints it.
pub fn format_clips(clips: &[ClipInfo]) -> String {
    let mut out = format!(
        "{:<24} {:<32} {:>8} {:>9} {:>10}  {}\n",
        "trigger time (UTC)", "triggers", "length_s", "covered_s", "size", "file"
    );
    for clip in clips {
        let name = clip
            .path
            .file_name()
            .map(|name| name.to_string_lossy().into_owned())
            .unwrap_or_default();
        match &clip.problem {
            Some(problem) => out.push_str(&format!("{name}: {problem}\n")),
            None => {
                out.push_str(&format!(
                    "{:<24} {:<32} {:>8.1} {:>9.1} {:>10}  {name}\n",
                    clip.first_trigger_utc,
                    clip.triggers.join(","),
                    clip.window_s,
                    clip.covered_s,
                    format_bytes(clip.size_bytes),
                ));
                if !clip.texts.is_empty() {
                    out.push_str(&format!("{:<24} {}\n", "", clip.texts));
                }
            }
        }
    }
    out
}
