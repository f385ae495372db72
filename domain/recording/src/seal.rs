//! Ending a recording file whose writing failed (the disk filled up under it): the file is cut
//! back to its last complete record and closed with a Data End record, a Footer without a
//! summary section and the closing magic, so every MCAP reader reads it to its end (readers
//! that want a summary fall back to scanning, as for any summary-less file).

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};

/// Data End (opcode 0x0F, 4 bytes: data section CRC, 0 = not computed).
const DATA_END: [u8; 13] = [0x0F, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
/// Footer (opcode 0x02, 20 bytes: summary start 0 and summary offset start 0 = no summary,
/// summary CRC 0).
const FOOTER: [u8; 29] = [
    0x02, 20, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
];

/// Bytes [`seal_cut_file`] appends.
pub const SEAL_BYTES: u64 = (DATA_END.len() + FOOTER.len() + mcap::MAGIC.len()) as u64;

/// Cuts `file` to its first `complete_bytes` (which must end on a record boundary, e.g.
/// [`crate::segment_writer::SegmentWriter::flushed_bytes`]) and appends the end records.
/// Returns the file's new size. Cutting frees the space the end records need, unless the
/// failure happened right at `complete_bytes`.
pub fn seal_cut_file(file: &mut File, complete_bytes: u64) -> std::io::Result<u64> {
    file.set_len(complete_bytes)?;
    file.seek(SeekFrom::Start(complete_bytes))?;
    let mut end = Vec::with_capacity(SEAL_BYTES as usize);
    end.extend_from_slice(&DATA_END);
    end.extend_from_slice(&FOOTER);
    end.extend_from_slice(mcap::MAGIC);
    if let Err(error) = file.write_all(&end) {
        // Leave the cut file (complete records, no end) rather than half an end record:
        // `harvest rec recover` and streaming readers read it as far as it goes.
        file.set_len(complete_bytes)?;
        return Err(error);
    }
    file.flush()?;
    Ok(complete_bytes + SEAL_BYTES)
}
