//! Opening a recording: the magic check that tells an MCAP file from anything else, and the
//! summary section (indexes and statistics) when the file has one.

use crate::record_lengths::{RecordSplit, le_u64, split_record};
use mcap::Summary;
use mcap::records::{Metadata, MetadataIndex, Record};
use mcap::sans_io::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// A recording cannot be read at all.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file cannot be opened.
    #[error("cannot open {path}: {source}")]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The file does not start with the MCAP magic.
    #[error("{path} is not an MCAP recording: {detail}")]
    NotMcap { path: PathBuf, detail: String },
    /// Reading failed midway (I/O error).
    #[error("reading {path} failed: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Opens `path`, checks the MCAP magic and returns the file positioned after it, with its size.
pub fn open_recording(path: &Path) -> Result<(File, u64), ReadError> {
    let mut file = File::open(path).map_err(|source| ReadError::Open {
        path: path.to_path_buf(),
        source,
    })?;
    let file_bytes = file
        .metadata()
        .map_err(|source| ReadError::Open {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    if file.metadata().is_ok_and(|metadata| metadata.is_dir()) {
        return Err(ReadError::NotMcap {
            path: path.to_path_buf(),
            detail: "it is a directory".to_owned(),
        });
    }
    let mut magic = [0u8; 8];
    let mut read = 0;
    while read < magic.len() {
        match file.read(&mut magic[read..]) {
            Ok(0) => break,
            Ok(n) => read += n,
            Err(error) if error.kind() == std::io::ErrorKind::Interrupted => {}
            Err(source) => {
                return Err(ReadError::Read {
                    path: path.to_path_buf(),
                    source,
                });
            }
        }
    }
    if read < magic.len() {
        return Err(ReadError::NotMcap {
            path: path.to_path_buf(),
            detail: format!("only {file_bytes} byte(s) long"),
        });
    }
    if magic != mcap::MAGIC {
        return Err(ReadError::NotMcap {
            path: path.to_path_buf(),
            detail: format!("it starts with {magic:02x?}, not the MCAP magic"),
        });
    }
    Ok((file, file_bytes))
}

/// The summary section, `Ok(None)` when the file has none (not finished), `Err` with the reason
/// when it is present but unreadable or the footer is missing.
pub fn read_summary(path: &Path) -> Result<Option<Summary>, String> {
    let (mut file, file_bytes) = open_recording(path).map_err(|error| error.to_string())?;
    check_summary_lengths(&mut file, file_bytes)?;
    let mut reader = SummaryReader::new_with_options(
        SummaryReaderOptions::default()
            .with_file_size(file_bytes)
            .with_record_length_limit(usize::try_from(file_bytes).unwrap_or(usize::MAX)),
    );
    while let Some(event) = reader.next_event() {
        match event.map_err(|error| crate::mcap_error::mcap_error_text(&error))? {
            SummaryReadEvent::ReadRequest(need) => {
                let read = file
                    .read(reader.insert(need))
                    .map_err(|error| error.to_string())?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let position = file.seek(to).map_err(|error| error.to_string())?;
                reader.notify_seeked(position);
            }
        }
    }
    Ok(reader.finish())
}

/// Bytes of the footer record (opcode, length, summary start, summary offset start, CRC).
const FOOTER_RECORD_BYTES: u64 = 1 + 8 + 8 + 8 + 4;

/// Checks the length prefixes of every record in the summary section the footer points to
/// ([`crate::record_lengths::check_length_prefixes`]) before the `mcap` crate's summary reader
/// parses them: its parser is the one that reserved what a length field claimed in the
/// scanner's case (fuzz `recording_file`), and for a bad length it says only "Record parse
/// failed"; the check names the record and the field. A file without a readable footer or
/// summary passes: the summary reader says what is missing.
fn check_summary_lengths(file: &mut File, file_bytes: u64) -> Result<(), String> {
    let Some(footer_start) = file_bytes.checked_sub(mcap::MAGIC.len() as u64 + FOOTER_RECORD_BYTES)
    else {
        return Ok(());
    };
    let mut footer = [0u8; FOOTER_RECORD_BYTES as usize];
    file.seek(SeekFrom::Start(footer_start))
        .map_err(|error| error.to_string())?;
    file.read_exact(&mut footer)
        .map_err(|error| error.to_string())?;
    if footer[0] != mcap::records::op::FOOTER {
        return Ok(());
    }
    let (summary_start, offsets_start) = (le_u64(&footer[9..17]), le_u64(&footer[17..25]));
    let summary_end = if offsets_start == 0 {
        footer_start
    } else {
        offsets_start
    };
    if summary_start == 0 || summary_start >= summary_end || summary_end > footer_start {
        return Ok(());
    }
    let mut section = vec![0u8; (summary_end - summary_start) as usize];
    file.seek(SeekFrom::Start(summary_start))
        .map_err(|error| error.to_string())?;
    file.read_exact(&mut section)
        .map_err(|error| error.to_string())?;
    let mut rest = section.as_slice();
    while !rest.is_empty() {
        // A record cut by the section's end: the summary reader reports it.
        let RecordSplit::Whole {
            opcode,
            body,
            rest: after,
        } = split_record(rest)
        else {
            break;
        };
        crate::record_lengths::check_length_prefixes(opcode, body)
            .map_err(|error| format!("summary section: {error}"))?;
        rest = after;
    }
    Ok(())
}

/// Reads the metadata records listed in a summary's metadata index.
pub fn read_indexed_metadata(
    path: &Path,
    indexes: &[MetadataIndex],
) -> Result<Vec<Metadata>, String> {
    let (mut file, file_bytes) = open_recording(path).map_err(|error| error.to_string())?;
    let mut records = Vec::new();
    let mut buffer = Vec::new();
    for index in indexes {
        if index.offset.saturating_add(index.length) > file_bytes || index.length < 9 {
            return Err(format!(
                "metadata index points outside the file (offset {})",
                index.offset
            ));
        }
        file.seek(SeekFrom::Start(index.offset))
            .map_err(|error| error.to_string())?;
        buffer.resize(index.length as usize, 0);
        file.read_exact(&mut buffer)
            .map_err(|error| error.to_string())?;
        match crate::record_lengths::parse_record(buffer[0], &buffer[9..]) {
            Ok(Record::Metadata(metadata)) => records.push(metadata),
            Ok(_) => {
                return Err(format!(
                    "metadata index at offset {} points to another record",
                    index.offset
                ));
            }
            Err(error) => return Err(error.to_string()),
        }
    }
    Ok(records)
}
