//! Serializing into plain CDR.

use super::{ENCAPSULATION_HEADER_BYTES, Endianness};

/// Writes one message: the encapsulation header, then the fields in order.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buffer: Vec<u8>,
    endianness: Endianness,
}

macro_rules! put {
    ($($name:ident: $ty:ty),* $(,)?) => {$(
        #[doc = concat!("Writes a `", stringify!($ty), "`, aligned to its size.")]
        pub fn $name(&mut self, value: $ty) {
            self.align(std::mem::size_of::<$ty>());
            match self.endianness {
                Endianness::Little => self.buffer.extend_from_slice(&value.to_le_bytes()),
                Endianness::Big => self.buffer.extend_from_slice(&value.to_be_bytes()),
            }
        }
    )*};
}

impl CdrWriter {
    /// A writer with the encapsulation header of `endianness` already written.
    pub fn new(endianness: Endianness) -> Self {
        Self::with_capacity(endianness, 64)
    }

    /// As [`Self::new`], with room for `capacity` bytes of fields.
    pub fn with_capacity(endianness: Endianness, capacity: usize) -> Self {
        let mut buffer = Vec::with_capacity(capacity + ENCAPSULATION_HEADER_BYTES);
        buffer.extend_from_slice(&endianness.encapsulation_header());
        Self { buffer, endianness }
    }

    /// Byte order of this stream.
    pub fn endianness(&self) -> Endianness {
        self.endianness
    }

    /// Pads with zeros to a multiple of `alignment` counted from the end of the header.
    pub fn align(&mut self, alignment: usize) {
        let offset = self.buffer.len() - ENCAPSULATION_HEADER_BYTES;
        let padding = (alignment - offset % alignment) % alignment;
        self.buffer.resize(self.buffer.len() + padding, 0);
    }

    put!(
        write_u16: u16, write_i16: i16, write_u32: u32, write_i32: i32, write_u64: u64,
        write_i64: i64, write_f32: f32, write_f64: f64,
    );

    pub fn write_u8(&mut self, value: u8) {
        self.buffer.push(value);
    }

    pub fn write_i8(&mut self, value: i8) {
        self.buffer.push(value as u8);
    }

    pub fn write_bool(&mut self, value: bool) {
        self.buffer.push(u8::from(value));
    }

    /// A string: its length with the terminating NUL, the bytes, the NUL.
    pub fn write_string(&mut self, value: &str) {
        self.write_length(value.len() + 1);
        self.buffer.extend_from_slice(value.as_bytes());
        self.buffer.push(0);
    }

    /// The element count of a sequence. Counts beyond `u32::MAX` cannot be represented in CDR
    /// and are written saturated (no ROS message of this crate comes near).
    pub fn write_length(&mut self, count: usize) {
        self.write_u32(u32::try_from(count).unwrap_or(u32::MAX));
    }

    /// A `uint8[]` / `byte[]` sequence: its count and the raw bytes.
    pub fn write_byte_sequence(&mut self, bytes: &[u8]) {
        self.write_length(bytes.len());
        self.buffer.extend_from_slice(bytes);
    }

    /// A sequence of any element, each written by `write`.
    pub fn write_sequence<T>(&mut self, items: &[T], mut write: impl FnMut(&mut Self, &T)) {
        self.write_length(items.len());
        for item in items {
            write(self, item);
        }
    }

    /// A `float64[]` sequence.
    pub fn write_f64_sequence(&mut self, values: &[f64]) {
        self.write_sequence(values, |w, v| w.write_f64(*v));
    }

    /// A fixed-size `float64[N]` array (no count on the wire).
    pub fn write_f64_array(&mut self, values: &[f64]) {
        for value in values {
            self.write_f64(*value);
        }
    }

    /// A `string[]` sequence.
    pub fn write_string_sequence(&mut self, values: &[String]) {
        self.write_sequence(values, |w, v| w.write_string(v));
    }

    /// Bytes of fields written so far (header excluded).
    pub fn body_len(&self) -> usize {
        self.buffer.len() - ENCAPSULATION_HEADER_BYTES
    }

    /// The serialized message, header included.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buffer
    }
}
