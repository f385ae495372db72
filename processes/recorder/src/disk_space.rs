//! Disk space held for the open segment, so the recorder can always finish its file when the
//! disk fills up (even when something else fills it).
//!
//! The writer asks for room up to an offset (what it is about to write plus what finishing the
//! file would then write, [`SegmentWriter::finish_bound_bytes`]) before each write. The room is
//! allocated ahead of the data with `fallocate(FALLOC_FL_KEEP_SIZE)`: the file's size does not
//! change, but the blocks are the file's, and writing into them cannot fail for lack of space.
//! When the file system cannot allocate them, the writer finishes the segment into what it
//! holds. On file systems without `fallocate` the free space (`fstatvfs`) is checked instead,
//! which is only as good as nothing else writing to the disk at the same moment.
//!
//! [`SegmentWriter::finish_bound_bytes`]: harvest_recording::segment_writer::SegmentWriter::finish_bound_bytes

use nix::errno::Errno;
use nix::fcntl::{FallocateFlags, fallocate};
use std::fs::File;
use std::path::Path;

/// Room is taken in steps of at least this much (fewer calls at 200 MB/s of frames).
const MIN_STEP_BYTES: u64 = 16 << 20;
/// Kept free beyond the asked-for room when only the free space can be checked.
const FREE_SPACE_MARGIN_BYTES: u64 = 4 << 20;

/// The disk has no room for what the segment needs.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("the disk is full: {needed_bytes} bytes needed, {free_bytes} free")]
pub struct OutOfSpace {
    pub needed_bytes: u64,
    pub free_bytes: u64,
}

/// How room is made sure of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Method {
    /// Blocks allocated ahead with `fallocate`.
    Allocate,
    /// The file system cannot allocate ahead: free space is checked.
    CheckFreeSpace,
}

/// The room held for one open segment file.
#[derive(Debug)]
pub struct SpaceReservation {
    /// A second descriptor of the segment file (the writer owns the first).
    file: File,
    /// Blocks up to this offset belong to the file.
    reserved_end: u64,
    method: Method,
}

impl SpaceReservation {
    /// Holds room for `file`, which is written from offset 0.
    pub fn new(file: &File) -> std::io::Result<Self> {
        Ok(Self {
            file: file.try_clone()?,
            reserved_end: 0,
            method: Method::Allocate,
        })
    }

    /// Makes sure the file can grow to `end_bytes` (with `written_bytes` written so far).
    pub fn ensure(&mut self, end_bytes: u64, written_bytes: u64) -> Result<(), OutOfSpace> {
        if end_bytes <= self.reserved_end {
            return Ok(());
        }
        if self.method == Method::Allocate {
            let step = (end_bytes - written_bytes).max(MIN_STEP_BYTES);
            // A whole step if the disk has it, else exactly what is needed.
            for target in [end_bytes.saturating_add(step), end_bytes] {
                match self.allocate_to(target) {
                    Ok(()) => {
                        self.reserved_end = target;
                        return Ok(());
                    }
                    Err(Errno::ENOSPC | Errno::EDQUOT) => continue,
                    Err(errno) => {
                        tracing::warn!(
                            %errno,
                            "cannot allocate recording space ahead; checking the free space instead"
                        );
                        self.method = Method::CheckFreeSpace;
                        break;
                    }
                }
            }
            if self.method == Method::Allocate {
                return Err(OutOfSpace {
                    needed_bytes: end_bytes.saturating_sub(self.reserved_end),
                    free_bytes: self.free_bytes().unwrap_or(0),
                });
            }
        }
        // Free-space check: what is not yet written must fit, with a margin.
        let needed_bytes = end_bytes.saturating_sub(written_bytes) + FREE_SPACE_MARGIN_BYTES;
        match self.free_bytes() {
            Ok(free_bytes) if free_bytes < needed_bytes => Err(OutOfSpace {
                needed_bytes,
                free_bytes,
            }),
            // Unknown free space: write and find out.
            _ => Ok(()),
        }
    }

    /// Gives back the blocks held beyond the end of the finished file.
    pub fn release(self) {
        if self.method != Method::Allocate {
            return;
        }
        // Cutting a file to its own size frees its blocks past the end.
        let result = self
            .file
            .metadata()
            .and_then(|metadata| self.file.set_len(metadata.len()));
        if let Err(error) = result {
            tracing::warn!(%error, "cannot give back the recording space held ahead");
        }
    }

    /// Bytes available to this process on the segment's file system.
    pub fn free_bytes(&self) -> std::io::Result<u64> {
        let stats = nix::sys::statvfs::fstatvfs(&self.file)?;
        Ok(available_bytes(&stats))
    }

    fn allocate_to(&self, target: u64) -> Result<(), Errno> {
        let offset = i64::try_from(self.reserved_end).map_err(|_| Errno::EFBIG)?;
        let length = i64::try_from(target - self.reserved_end).map_err(|_| Errno::EFBIG)?;
        fallocate(
            &self.file,
            FallocateFlags::FALLOC_FL_KEEP_SIZE,
            offset,
            length,
        )
    }
}

/// Bytes available to this process in the file system holding `dir`.
pub fn free_bytes_in(dir: &Path) -> std::io::Result<u64> {
    let stats = nix::sys::statvfs::statvfs(dir)?;
    Ok(available_bytes(&stats))
}

fn available_bytes(stats: &nix::sys::statvfs::Statvfs) -> u64 {
    stats
        .blocks_available()
        .saturating_mul(stats.fragment_size())
}
