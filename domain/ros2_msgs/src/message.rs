//! The one trait every message type implements: its description and its CDR fields.

use crate::cdr::{CdrError, CdrReader, CdrWriter, Endianness};
use crate::type_description::MessageType;

/// A serialized message of a known type could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{type_name}: {source}")]
pub struct DecodeError {
    pub type_name: &'static str,
    pub source: CdrError,
}

/// A ROS 2 message type: what it is ([`RosMessage::TYPE`]) and how its fields go on the wire.
pub trait RosMessage: Sized {
    /// The type's description (name, fields), from which its definition text and hash come.
    const TYPE: &'static MessageType;

    /// Writes the fields in order (no encapsulation header: nested messages use this too).
    fn write_fields(&self, writer: &mut CdrWriter);

    /// Reads the fields in order.
    fn read_fields(reader: &mut CdrReader<'_>) -> Result<Self, CdrError>;

    /// The serialized message, little endian (what ROS 2 on x86 and ARM writes).
    fn to_cdr(&self) -> Vec<u8> {
        self.to_cdr_in(Endianness::Little)
    }

    /// The serialized message in the given byte order.
    fn to_cdr_in(&self, endianness: Endianness) -> Vec<u8> {
        let mut writer = CdrWriter::new(endianness);
        self.write_fields(&mut writer);
        writer.into_bytes()
    }

    /// Decodes a serialized message (either byte order). Bytes after the last field are
    /// allowed: some writers pad a message to a multiple of 4.
    fn from_cdr(bytes: &[u8]) -> Result<Self, DecodeError> {
        let error = |source| DecodeError {
            type_name: Self::TYPE.name,
            source,
        };
        let mut reader = CdrReader::new(bytes).map_err(error)?;
        Self::read_fields(&mut reader).map_err(error)
    }
}
