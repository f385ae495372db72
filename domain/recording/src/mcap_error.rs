//! Readable text for MCAP library errors (whose own messages omit their I/O cause).

use mcap::McapError;
use std::error::Error as _;

/// The error and every cause under it, e.g. `I/O error ...: No space left on device (os error 28)`.
pub fn mcap_error_text(error: &McapError) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        text.push_str(": ");
        text.push_str(&cause.to_string());
        source = cause.source();
    }
    if is_disk_full(error) {
        text.push_str(" (the disk is full)");
    }
    text
}

/// True when the error comes from a full file system (or an exhausted disk quota).
pub fn is_disk_full(error: &McapError) -> bool {
    matches!(error, McapError::Io(io) if is_out_of_space(io))
}

/// True for the I/O errors of a full file system or an exhausted disk quota.
pub fn is_out_of_space(error: &std::io::Error) -> bool {
    matches!(
        error.kind(),
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
    )
}
