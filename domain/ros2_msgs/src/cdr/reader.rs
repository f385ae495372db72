//! Deserializing plain CDR, with every length checked against the bytes there are.

use super::{CdrError, ENCAPSULATION_HEADER_BYTES, Endianness};

/// Reads one message's fields in order.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    /// The bytes after the encapsulation header (alignment counts from their start).
    body: &'a [u8],
    position: usize,
    endianness: Endianness,
}

macro_rules! get {
    ($($name:ident: $ty:ty),* $(,)?) => {$(
        #[doc = concat!("Reads a `", stringify!($ty), "`, aligned to its size.")]
        pub fn $name(&mut self) -> Result<$ty, CdrError> {
            const SIZE: usize = std::mem::size_of::<$ty>();
            self.align(SIZE, stringify!($ty))?;
            let bytes: [u8; SIZE] = self.take(SIZE, stringify!($ty))?.try_into().map_err(|_| {
                self.truncated(stringify!($ty))
            })?;
            Ok(match self.endianness {
                Endianness::Little => <$ty>::from_le_bytes(bytes),
                Endianness::Big => <$ty>::from_be_bytes(bytes),
            })
        }
    )*};
}

impl<'a> CdrReader<'a> {
    /// Reads the encapsulation header of a serialized message (plain CDR, either byte order;
    /// the options bytes are ignored).
    pub fn new(message: &'a [u8]) -> Result<Self, CdrError> {
        let Some((header, body)) = message.split_at_checked(ENCAPSULATION_HEADER_BYTES) else {
            return Err(CdrError::NoHeader { len: message.len() });
        };
        let identifier = u16::from_be_bytes([header[0], header[1]]);
        let endianness = match identifier {
            0x0000 => Endianness::Big,
            0x0001 => Endianness::Little,
            _ => return Err(CdrError::Encapsulation { identifier }),
        };
        Ok(Self {
            body,
            position: 0,
            endianness,
        })
    }

    /// Byte order of the message.
    pub fn endianness(&self) -> Endianness {
        self.endianness
    }

    /// Bytes not read yet.
    pub fn remaining(&self) -> usize {
        self.body.len() - self.position
    }

    fn truncated(&self, what: &'static str) -> CdrError {
        CdrError::Truncated {
            what,
            offset: self.position,
            len: self.body.len(),
        }
    }

    fn align(&mut self, alignment: usize, what: &'static str) -> Result<(), CdrError> {
        let padding = (alignment - self.position % alignment) % alignment;
        if padding > self.remaining() {
            return Err(self.truncated(what));
        }
        self.position += padding;
        Ok(())
    }

    fn take(&mut self, len: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let end = self
            .position
            .checked_add(len)
            .filter(|end| *end <= self.body.len())
            .ok_or_else(|| self.truncated(what))?;
        let bytes = &self.body[self.position..end];
        self.position = end;
        Ok(bytes)
    }

    get!(
        read_u16: u16, read_i16: i16, read_u32: u32, read_i32: i32, read_u64: u64,
        read_i64: i64, read_f32: f32, read_f64: f64,
    );

    pub fn read_u8(&mut self) -> Result<u8, CdrError> {
        Ok(self.take(1, "u8")?[0])
    }

    pub fn read_i8(&mut self) -> Result<i8, CdrError> {
        Ok(self.take(1, "i8")?[0] as i8)
    }

    pub fn read_bool(&mut self) -> Result<bool, CdrError> {
        let offset = self.position;
        match self.take(1, "bool")?[0] {
            0 => Ok(false),
            1 => Ok(true),
            value => Err(CdrError::Bool { offset, value }),
        }
    }

    /// A sequence's element count, checked against the bytes left for elements of at least
    /// `min_element_bytes` each (so a damaged count never allocates more than the message holds).
    pub fn read_length(
        &mut self,
        what: &'static str,
        min_element_bytes: usize,
    ) -> Result<usize, CdrError> {
        let count = self.read_u32()?;
        let offset = self.position;
        let needed = (count as usize).saturating_mul(min_element_bytes);
        if needed > self.remaining() {
            return Err(CdrError::Length {
                what,
                offset,
                count,
                remaining: self.remaining(),
            });
        }
        Ok(count as usize)
    }

    /// A string (its length counts the terminating NUL, which must be there).
    pub fn read_string(&mut self) -> Result<String, CdrError> {
        let len = self.read_length("string", 1)?;
        let offset = self.position;
        if len == 0 {
            // Some writers send an empty string as length 0 without the NUL.
            return Ok(String::new());
        }
        let bytes = self.take(len, "string")?;
        let Some((0, text)) = bytes.split_last() else {
            return Err(CdrError::String {
                offset,
                problem: "no terminating NUL",
            });
        };
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::String {
            offset,
            problem: "not UTF-8",
        })
    }

    /// A `uint8[]` / `byte[]` sequence, borrowed from the message.
    pub fn read_byte_sequence(&mut self) -> Result<&'a [u8], CdrError> {
        let len = self.read_length("uint8[]", 1)?;
        self.take(len, "uint8[]")
    }

    /// A sequence of any element, each read by `read`; `min_element_bytes` bounds the count.
    pub fn read_sequence<T>(
        &mut self,
        what: &'static str,
        min_element_bytes: usize,
        mut read: impl FnMut(&mut Self) -> Result<T, CdrError>,
    ) -> Result<Vec<T>, CdrError> {
        let len = self.read_length(what, min_element_bytes)?;
        let mut items = Vec::with_capacity(len);
        for _ in 0..len {
            items.push(read(self)?);
        }
        Ok(items)
    }

    /// A `float64[]` sequence.
    pub fn read_f64_sequence(&mut self) -> Result<Vec<f64>, CdrError> {
        self.read_sequence("float64[]", 8, Self::read_f64)
    }

    /// A fixed-size `float64[N]` array.
    pub fn read_f64_array<const N: usize>(&mut self) -> Result<[f64; N], CdrError> {
        let mut values = [0.0; N];
        for value in &mut values {
            *value = self.read_f64()?;
        }
        Ok(values)
    }

    /// A `string[]` sequence.
    pub fn read_string_sequence(&mut self) -> Result<Vec<String>, CdrError> {
        self.read_sequence("string[]", 4, Self::read_string)
    }
}

#[cfg(test)]
mod tests {
    use super::super::CdrWriter;
    use super::*;

    #[test]
    fn primitives_round_trip_in_both_byte_orders_with_alignment() {
        for endianness in [Endianness::Little, Endianness::Big] {
            let mut w = CdrWriter::new(endianness);
            w.write_u8(7);
            w.write_f64(-2.5);
            w.write_bool(true);
            w.write_u16(0xBEEF);
            w.write_string("abc");
            w.write_i64(-3);
            w.write_byte_sequence(&[1, 2, 3]);
            w.write_f32(1.5);
            let bytes = w.into_bytes();
            // u8 at 0, pad to 8, f64 at 8..16, bool 16, pad, u16 at 18, string len at 20,
            // "abc\0" at 24..28, i64 at 32, seq len at 40, bytes 44..47, pad, f32 at 48.
            assert_eq!(bytes.len(), 4 + 52);
            assert_eq!(&bytes[..4], &endianness.encapsulation_header());
            let mut r = CdrReader::new(&bytes).unwrap();
            assert_eq!(r.endianness(), endianness);
            assert_eq!(r.read_u8().unwrap(), 7);
            assert_eq!(r.read_f64().unwrap(), -2.5);
            assert!(r.read_bool().unwrap());
            assert_eq!(r.read_u16().unwrap(), 0xBEEF);
            assert_eq!(r.read_string().unwrap(), "abc");
            assert_eq!(r.read_i64().unwrap(), -3);
            assert_eq!(r.read_byte_sequence().unwrap(), &[1, 2, 3]);
            assert_eq!(r.read_f32().unwrap(), 1.5);
            assert_eq!(r.remaining(), 0);
        }
    }

    #[test]
    fn known_little_and_big_endian_bytes() {
        let mut w = CdrWriter::new(Endianness::Little);
        w.write_u32(0x0102_0304);
        assert_eq!(w.into_bytes(), [0, 1, 0, 0, 4, 3, 2, 1]);
        let mut w = CdrWriter::new(Endianness::Big);
        w.write_u32(0x0102_0304);
        assert_eq!(w.into_bytes(), [0, 0, 0, 0, 1, 2, 3, 4]);
    }

    #[test]
    fn damaged_input_is_refused_not_panicked_on() {
        assert!(matches!(
            CdrReader::new(&[0, 1]),
            Err(CdrError::NoHeader { len: 2 })
        ));
        assert!(matches!(
            CdrReader::new(&[0, 7, 0, 0]),
            Err(CdrError::Encapsulation { identifier: 7 })
        ));
        // A sequence claiming 1000 elements in a 8-byte body.
        let bytes = [0, 1, 0, 0, 0xE8, 3, 0, 0, 1, 2, 3, 4];
        let mut r = CdrReader::new(&bytes).unwrap();
        assert!(matches!(
            r.read_byte_sequence(),
            Err(CdrError::Length { count: 1000, .. })
        ));
        let bytes = [0, 1, 0, 0, 2, 0, 0, 0, b'a', b'b'];
        let mut r = CdrReader::new(&bytes).unwrap();
        assert!(matches!(r.read_string(), Err(CdrError::String { .. })));
        let bytes = [0, 1, 0, 0, 1, 2];
        let mut r = CdrReader::new(&bytes).unwrap();
        assert!(matches!(r.read_u32(), Err(CdrError::Truncated { .. })));
        let mut r = CdrReader::new(&[0, 1, 0, 0, 2]).unwrap();
        assert!(matches!(
            r.read_bool(),
            Err(CdrError::Bool { value: 2, .. })
        ));
    }
}
