//! MCAP records parsed only after their length prefixes are checked against the record.
//!
//! The `mcap` crate reserves whatever a string's or byte array's length prefix claims before it
//! reads the bytes: a 5-byte Header record whose profile claims 4 GiB made the scanner allocate
//! 4 GiB (found by the `recording_file` fuzz target, see `tests/decoder_properties.rs`). Every
//! length prefix of a record is therefore checked to fit in what remains of the record first.

use mcap::records::{Record, op};

/// Why a record could not be parsed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A length prefix claims more bytes than the record has left.
    #[error(
        "record opcode 0x{opcode:02x}: {field} claims {claimed_bytes} bytes but only {remaining_bytes} remain in the record"
    )]
    LengthPastEnd {
        opcode: u8,
        field: &'static str,
        claimed_bytes: u64,
        remaining_bytes: u64,
    },
    /// The `mcap` crate's own error, with its causes.
    #[error("{0}")]
    Mcap(String),
}

/// Bytes of a record's frame before its body: the opcode and the u64 length prefix.
pub const RECORD_PREFIX_BYTES: usize = 9;

/// The record at the start of a run of records (chunk content, the summary section).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordSplit<'a> {
    /// A whole record: its opcode, its body and the bytes after it.
    Whole {
        opcode: u8,
        body: &'a [u8],
        rest: &'a [u8],
    },
    /// Fewer bytes than an opcode and a length prefix.
    PrefixCut,
    /// The length prefix claims more bytes than follow it.
    PastEnd { claimed_bytes: u64 },
}

/// Splits the first record off `bytes` (not empty) by its opcode and length prefix.
pub fn split_record(bytes: &[u8]) -> RecordSplit<'_> {
    let Some((&opcode, after_opcode)) = bytes.split_first() else {
        return RecordSplit::PrefixCut;
    };
    match split_length_prefixed(after_opcode, RECORD_PREFIX_BYTES - 1) {
        LengthPrefixed::Cut => RecordSplit::PrefixCut,
        LengthPrefixed::PastEnd { claimed_bytes, .. } => RecordSplit::PastEnd { claimed_bytes },
        LengthPrefixed::Whole { value, rest } => RecordSplit::Whole {
            opcode,
            body: value,
            rest,
        },
    }
}

/// A value behind a little-endian length prefix.
enum LengthPrefixed<'a> {
    /// Fewer bytes than the prefix.
    Cut,
    /// The prefix claims more bytes than the `remaining_bytes` after it.
    PastEnd {
        claimed_bytes: u64,
        remaining_bytes: u64,
    },
    /// The value and the bytes after it.
    Whole { value: &'a [u8], rest: &'a [u8] },
}

/// Splits the value behind a little-endian length prefix of `width` bytes (1..=8) off `bytes`.
fn split_length_prefixed(bytes: &[u8], width: usize) -> LengthPrefixed<'_> {
    let Some((prefix, after)) = bytes.split_at_checked(width) else {
        return LengthPrefixed::Cut;
    };
    let claimed_bytes = le_u64(prefix);
    match usize::try_from(claimed_bytes)
        .ok()
        .and_then(|claimed| after.split_at_checked(claimed))
    {
        Some((value, rest)) => LengthPrefixed::Whole { value, rest },
        None => LengthPrefixed::PastEnd {
            claimed_bytes,
            remaining_bytes: after.len() as u64,
        },
    }
}

/// The little-endian unsigned integer in `bytes` (at most 8; fewer are zero-extended).
pub(crate) fn le_u64(bytes: &[u8]) -> u64 {
    let mut wide = [0u8; 8];
    let width = bytes.len().min(8);
    wide[..width].copy_from_slice(&bytes[..width]);
    u64::from_le_bytes(wide)
}

/// One field of a record's layout.
enum Field {
    /// A fixed number of bytes.
    Fixed(usize),
    /// A u32 length prefix then that many bytes.
    Prefixed32(&'static str),
    /// A u64 length prefix then that many bytes.
    Prefixed64(&'static str),
    /// A u32 byte-length prefix then string pairs, each string with its u32 length prefix.
    StringMap(&'static str),
}

/// The layout of the records with length prefixes (MCAP specification, "Records").
fn layout(opcode: u8) -> &'static [Field] {
    use Field::{Fixed, Prefixed32, Prefixed64, StringMap};
    match opcode {
        op::HEADER => &[Prefixed32("profile"), Prefixed32("library")],
        op::SCHEMA => &[
            Fixed(2),
            Prefixed32("schema name"),
            Prefixed32("schema encoding"),
            Prefixed32("schema data"),
        ],
        op::CHANNEL => &[
            Fixed(4),
            Prefixed32("topic"),
            Prefixed32("message encoding"),
            StringMap("channel metadata"),
        ],
        op::CHUNK => &[Fixed(28), Prefixed32("compression"), Prefixed64("records")],
        op::MESSAGE_INDEX => &[Fixed(2), Prefixed32("message index entries")],
        op::CHUNK_INDEX => &[
            Fixed(32),
            Prefixed32("message index offsets"),
            Fixed(8),
            Prefixed32("compression"),
        ],
        op::ATTACHMENT => &[
            Fixed(16),
            Prefixed32("attachment name"),
            Prefixed32("media type"),
            Prefixed64("attachment data"),
        ],
        op::ATTACHMENT_INDEX => &[
            Fixed(40),
            Prefixed32("attachment name"),
            Prefixed32("media type"),
        ],
        op::STATISTICS => &[Fixed(42), Prefixed32("channel message counts")],
        op::METADATA => &[Prefixed32("metadata name"), StringMap("metadata")],
        op::METADATA_INDEX => &[Fixed(16), Prefixed32("metadata name")],
        _ => &[],
    }
}

/// A length-prefixed value and the bytes after it.
type ValueAndRest<'a> = (&'a [u8], &'a [u8]);

/// Reads a length prefix of `width` bytes at the start of `rest` and checks that it fits;
/// `Ok(None)` when the prefix itself is cut (the `mcap` crate reports that).
fn prefixed<'a>(
    opcode: u8,
    field: &'static str,
    width: usize,
    rest: &'a [u8],
) -> Result<Option<ValueAndRest<'a>>, RecordError> {
    match split_length_prefixed(rest, width) {
        LengthPrefixed::Cut => Ok(None),
        LengthPrefixed::Whole { value, rest } => Ok(Some((value, rest))),
        LengthPrefixed::PastEnd {
            claimed_bytes,
            remaining_bytes,
        } => Err(RecordError::LengthPastEnd {
            opcode,
            field,
            claimed_bytes,
            remaining_bytes,
        }),
    }
}

/// Checks every length prefix of the record `opcode` with body `body`.
pub fn check_length_prefixes(opcode: u8, body: &[u8]) -> Result<(), RecordError> {
    let mut rest = body;
    for field in layout(opcode) {
        let next = match field {
            Field::Fixed(bytes) => rest.get(*bytes..),
            Field::Prefixed32(name) => prefixed(opcode, name, 4, rest)?.map(|(_, after)| after),
            Field::Prefixed64(name) => prefixed(opcode, name, 8, rest)?.map(|(_, after)| after),
            Field::StringMap(name) => match prefixed(opcode, name, 4, rest)? {
                Some((mut map, after)) => {
                    while !map.is_empty() {
                        match prefixed(opcode, name, 4, map)? {
                            Some((_, after_entry)) => map = after_entry,
                            None => break,
                        }
                    }
                    Some(after)
                }
                None => None,
            },
        };
        match next {
            Some(after) => rest = after,
            // Cut inside a fixed field or a prefix: the `mcap` crate reports it.
            None => return Ok(()),
        }
    }
    Ok(())
}

/// [`mcap::parse_record`] after [`check_length_prefixes`].
pub fn parse_record(opcode: u8, body: &[u8]) -> Result<Record<'_>, RecordError> {
    check_length_prefixes(opcode, body)?;
    mcap::parse_record(opcode, body)
        .map_err(|error| RecordError::Mcap(crate::mcap_error::mcap_error_text(&error)))
}
