//! The recordings directory: segment file names and the size bound (oldest segments removed
//! first).
//!
//! Segment files are named `<prefix>-<domain>-<UTC start>-<segment>.mcap`, e.g.
//! `harvest-default-20250301T123456Z-000.mcap`. Only files named `<prefix>-*.mcap` count
//! towards the bound and are ever removed; exports and other files in the directory are left
//! alone.

use std::fs::{File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Creates the next segment file of a session, never overwriting an existing file.
pub fn create_segment(
    dir: &Path,
    prefix: &str,
    domain: &str,
    session_utc: &str,
    segment: u32,
) -> io::Result<(PathBuf, File)> {
    let stem = format!("{prefix}-{domain}-{session_utc}-{segment:03}");
    for attempt in 0..1000u32 {
        let name = if attempt == 0 {
            format!("{stem}.mcap")
        } else {
            format!("{stem}-{attempt}.mcap")
        };
        let path = dir.join(name);
        match OpenOptions::new()
            .write(true)
            .read(true)
            .create_new(true)
            .open(&path)
        {
            Ok(file) => return Ok((path, file)),
            Err(error) if error.kind() == io::ErrorKind::AlreadyExists => continue,
            Err(error) => return Err(error),
        }
    }
    Err(io::Error::new(
        io::ErrorKind::AlreadyExists,
        format!("{stem}: 1000 files of that name exist"),
    ))
}

/// A recording file counted by the size bound.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SegmentFile {
    pub path: PathBuf,
    pub size_bytes: u64,
    pub modified: SystemTime,
}

/// The `<prefix>-*.mcap` files in `dir`, oldest first (by modification time, then name).
pub fn list_segments(dir: &Path, prefix: &str) -> io::Result<Vec<SegmentFile>> {
    let mut files = Vec::new();
    let name_start = format!("{prefix}-");
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let name = name.to_string_lossy();
        if !name.starts_with(&name_start) || !name.ends_with(".mcap") {
            continue;
        }
        let metadata = entry.metadata()?;
        if !metadata.is_file() {
            continue;
        }
        files.push(SegmentFile {
            path: entry.path(),
            size_bytes: metadata.len(),
            modified: metadata.modified().unwrap_or(SystemTime::UNIX_EPOCH),
        });
    }
    files.sort_by(|a, b| {
        a.modified
            .cmp(&b.modified)
            .then_with(|| a.path.cmp(&b.path))
    });
    Ok(files)
}

/// Removes the oldest segment files until the total is at most `max_total_bytes`, never
/// removing `keep` (the segment being written). Returns the removed files.
pub fn enforce_size_bound(
    dir: &Path,
    prefix: &str,
    max_total_bytes: u64,
    keep: Option<&Path>,
) -> io::Result<Vec<SegmentFile>> {
    let files = list_segments(dir, prefix)?;
    let mut total: u64 = files.iter().map(|file| file.size_bytes).sum();
    let mut removed = Vec::new();
    for file in files {
        if total <= max_total_bytes {
            break;
        }
        if keep.is_some_and(|keep| keep == file.path) {
            continue;
        }
        match std::fs::remove_file(&file.path) {
            Ok(()) => {
                tracing::info!(path = %file.path.display(), size_bytes = file.size_bytes, "size bound: removed oldest recording");
                total -= file.size_bytes;
                removed.push(file);
            }
            Err(error) => {
                tracing::warn!(path = %file.path.display(), %error, "size bound: cannot remove recording");
            }
        }
    }
    Ok(removed)
}

/// Removes the `<prefix>-*.mcap` files in `dir` last written more than `max_age` before `now`,
/// except `keep` (the segment being written). Returns the removed files.
pub fn enforce_age_bound(
    dir: &Path,
    prefix: &str,
    max_age: std::time::Duration,
    now: SystemTime,
    keep: Option<&Path>,
) -> io::Result<Vec<SegmentFile>> {
    let Some(oldest_kept) = now.checked_sub(max_age) else {
        return Ok(Vec::new());
    };
    let mut removed = Vec::new();
    for file in list_segments(dir, prefix)? {
        if file.modified >= oldest_kept {
            break;
        }
        if keep.is_some_and(|keep| keep == file.path) {
            continue;
        }
        match std::fs::remove_file(&file.path) {
            Ok(()) => {
                tracing::info!(path = %file.path.display(), max_age_s = max_age.as_secs(), "age bound: removed recording");
                removed.push(file);
            }
            Err(error) => {
                tracing::warn!(path = %file.path.display(), %error, "age bound: cannot remove recording");
            }
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("harvest-recorder-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    #[test]
    fn names_never_collide() {
        let dir = scratch_dir("names");
        let (first, _) = create_segment(&dir, "rec", "d", "20250101T000000Z", 0).expect("first");
        let (second, _) = create_segment(&dir, "rec", "d", "20250101T000000Z", 0).expect("second");
        assert_ne!(first, second);
        assert!(first.ends_with("rec-d-20250101T000000Z-000.mcap"));
        assert!(second.ends_with("rec-d-20250101T000000Z-000-1.mcap"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn removes_oldest_first_and_keeps_others() {
        let dir = scratch_dir("bound");
        let old = SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_000);
        for (index, name) in ["rec-a.mcap", "rec-b.mcap", "rec-c.mcap"]
            .iter()
            .enumerate()
        {
            let path = dir.join(name);
            std::fs::write(&path, vec![0u8; 100]).expect("write");
            let file = File::options().write(true).open(&path).expect("open");
            file.set_modified(old + std::time::Duration::from_secs(index as u64))
                .expect("mtime");
        }
        std::fs::write(dir.join("export.mcap"), vec![0u8; 1000]).expect("write");
        let removed =
            enforce_size_bound(&dir, "rec", 150, Some(&dir.join("rec-a.mcap"))).expect("bound");
        let removed: Vec<_> = removed
            .iter()
            .map(|f| f.path.file_name().map(|n| n.to_owned()))
            .collect();
        // rec-a is kept (being written), so rec-b (next oldest) then rec-c go... until <= 150.
        assert_eq!(
            removed,
            vec![Some("rec-b.mcap".into()), Some("rec-c.mcap".into())]
        );
        assert!(dir.join("rec-a.mcap").exists());
        assert!(dir.join("export.mcap").exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn age_bound_removes_only_old_segments() {
        let dir = scratch_dir("age");
        let (old, _) = create_segment(&dir, "rec", "d", "20250101T000000Z", 0).expect("old");
        let (new, _) = create_segment(&dir, "rec", "d", "20250101T000000Z", 1).expect("new");
        std::fs::write(dir.join("other.mcap"), b"x").expect("other");
        let now = SystemTime::now();
        let hour = std::time::Duration::from_secs(3600);
        std::fs::File::options()
            .write(true)
            .open(&old)
            .expect("open")
            .set_modified(now - 3 * hour)
            .expect("age");
        let removed = enforce_age_bound(&dir, "rec", 2 * hour, now, None).expect("bound");
        assert_eq!(removed.len(), 1);
        assert_eq!(removed[0].path, old);
        assert!(new.exists() && !old.exists() && dir.join("other.mcap").exists());
        // The segment being written stays whatever its age.
        let removed =
            enforce_age_bound(&dir, "rec", hour, now + 3 * hour, Some(&new)).expect("bound");
        assert!(removed.is_empty() && new.exists());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
