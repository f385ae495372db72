//! OMG CDR as ROS 2 puts it on the wire and in bags: XCDR1 (plain CDR), a 4-byte encapsulation
//! header (`00 01 00 00` little endian, `00 00 00 00` big endian), then the fields in order,
//! each primitive aligned to its own size (8 for 64-bit types) counted from the end of the
//! header; strings as a `u32` length that includes the terminating NUL, sequences as a `u32`
//! element count.

mod reader;
mod writer;

pub use reader::CdrReader;
pub use writer::CdrWriter;

/// Byte order of a CDR stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endianness {
    Little,
    Big,
}

/// Size of the encapsulation header in front of every serialized message.
pub const ENCAPSULATION_HEADER_BYTES: usize = 4;

impl Endianness {
    /// The encapsulation header of plain CDR in this byte order.
    pub fn encapsulation_header(self) -> [u8; ENCAPSULATION_HEADER_BYTES] {
        match self {
            Self::Big => [0x00, 0x00, 0x00, 0x00],
            Self::Little => [0x00, 0x01, 0x00, 0x00],
        }
    }
}

/// A serialized message could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// The message is shorter than its encapsulation header.
    #[error("{len} byte(s): shorter than the 4-byte CDR encapsulation header")]
    NoHeader { len: usize },
    /// The representation identifier is not plain CDR (XCDR1) in either byte order.
    #[error(
        "encapsulation {identifier:#06x} is not plain CDR (0x0000 big endian, 0x0001 little endian)"
    )]
    Encapsulation { identifier: u16 },
    /// The data ends before a value.
    #[error("truncated at byte {offset} reading {what} ({len} bytes after the header)")]
    Truncated {
        what: &'static str,
        offset: usize,
        len: usize,
    },
    /// A sequence or string claims more elements than the bytes left could hold.
    #[error(
        "{what} at byte {offset} claims {count} element(s), more than the {remaining} byte(s) left"
    )]
    Length {
        what: &'static str,
        offset: usize,
        count: u32,
        remaining: usize,
    },
    /// A string is not NUL-terminated or not UTF-8.
    #[error("string at byte {offset}: {problem}")]
    String {
        offset: usize,
        problem: &'static str,
    },
    /// A boolean byte other than 0 or 1.
    #[error("bool at byte {offset} is {value}, not 0 or 1")]
    Bool { offset: usize, value: u8 },
}
