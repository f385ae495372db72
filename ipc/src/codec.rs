//! The one place that knows how messages are encoded for recordings and copying transports.
//!
//! Encoding: bincode 2 over serde, `config::standard().with_fixed_int_encoding()`: little-endian,
//! fixed-width integers (u8/u16/u32/u64 as 1/2/4/8 bytes, f32/f64 IEEE-754), `bool` as one byte,
//! sequences and strings prefixed by a u64 length, structs as their fields in declaration order
//! with no padding, fixed arrays without a length prefix. The constant [`ENCODING`] names this in
//! MCAP schemas and channels so another tool can decode it. Swapping the codec means changing
//! this file only.

use bincode::config::Config;
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Name of the encoding, written into MCAP channel `message_encoding` and schema `encoding`.
pub const ENCODING: &str = "bincode2-fixint-le";

/// Why a message could not be encoded or decoded.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    /// The serializer failed (a type that bincode cannot represent).
    #[error("encoding failed: {0}")]
    Encode(String),
    /// The bytes are not a valid message of the expected type.
    #[error("decoding failed: {0}")]
    Decode(String),
    /// The bytes are valid but of the wrong length for the expected type.
    #[error("message has {actual} bytes, expected {expected}")]
    Length {
        /// Bytes the payload type encodes to.
        expected: usize,
        /// Bytes the message has.
        actual: usize,
    },
}

/// Most bytes one decode may read or set aside for containers. A length prefix is outside
/// data: without a bound, a corrupt `u64` length in a recording or a copied message makes the
/// decoder allocate that many bytes (an abort, not an error). The largest part of any payload
/// decoded through the codec is about 10 KB (`GroundTruth`'s 256 apples); frames, images and
/// point clouds decode their pixels and points outside it.
pub const DECODE_LIMIT_BYTES: usize = 4 << 20;

fn config() -> impl Config {
    bincode::config::standard().with_fixed_int_encoding()
}

fn decode_config() -> impl Config {
    bincode::config::standard()
        .with_fixed_int_encoding()
        .with_limit::<DECODE_LIMIT_BYTES>()
}

/// Appends the encoding of `value` to `out`.
pub fn encode_into<T: Serialize + ?Sized>(value: &T, out: &mut Vec<u8>) -> Result<(), CodecError> {
    bincode::serde::encode_into_std_write(value, out, config())
        .map(|_| ())
        .map_err(|error| CodecError::Encode(error.to_string()))
}

/// Decodes one value from the start of `bytes`; returns it and the bytes consumed.
pub fn decode_prefix<T: DeserializeOwned>(bytes: &[u8]) -> Result<(T, usize), CodecError> {
    bincode::serde::decode_from_slice(bytes, decode_config())
        .map_err(|error| CodecError::Decode(error.to_string()))
}

/// Decodes one value that must span all of `bytes`.
pub fn decode_exact<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CodecError> {
    let (value, used) = decode_prefix(bytes)?;
    if used != bytes.len() {
        return Err(CodecError::Length {
            expected: used,
            actual: bytes.len(),
        });
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
    struct Sample {
        a: u16,
        b: f64,
        c: [u8; 3],
    }

    #[test]
    fn fixed_int_layout_and_round_trip() {
        let sample = Sample {
            a: 0x0102,
            b: 1.5,
            c: [7, 8, 9],
        };
        let mut bytes = Vec::new();
        encode_into(&sample, &mut bytes).expect("encode");
        assert_eq!(bytes.len(), 2 + 8 + 3);
        assert_eq!(&bytes[..2], &[0x02, 0x01]);
        assert_eq!(decode_exact::<Sample>(&bytes).expect("decode"), sample);
        assert!(decode_exact::<Sample>(&bytes[..5]).is_err());
    }

    /// Found by the recording property tests: a string whose length prefix is absurd made the
    /// decoder try to allocate that many bytes and abort the process.
    #[test]
    fn an_absurd_length_prefix_is_an_error_not_an_allocation() {
        let mut bytes = 0x36e0_c5b0_d16a_f68e_u64.to_le_bytes().to_vec();
        bytes.extend_from_slice(b"abc");
        let error = decode_exact::<String>(&bytes).expect_err("absurd length");
        assert!(matches!(error, CodecError::Decode(_)), "{error}");
        let mut bytes = ((DECODE_LIMIT_BYTES + 1) as u64).to_le_bytes().to_vec();
        bytes.extend_from_slice(&[0; 16]);
        assert!(decode_exact::<Vec<u8>>(&bytes).is_err());
    }
}
