//! Fixed-size benchmark payloads for the size sweep (the catalogue's channels have fixed types).

use harvest_ipc::codec::{self, CodecError};
use harvest_ipc::{AnyBitPattern, Describe, Header, Payload};
use iceoryx2::prelude::ZeroCopySend;

/// Bytes in front of [`BenchPayload::bytes`]: the [`Header`] (24) and the phase code (8).
pub const BENCH_PAYLOAD_OVERHEAD: usize = std::mem::size_of::<Header>() + 8;

/// A benchmark message of `BENCH_PAYLOAD_OVERHEAD + N` bytes. `N` must be a multiple of 8 so
/// the struct has no padding (checked at compile time by the `AnyBitPattern` derive when the
/// transport opens a channel of it, and by [`BenchPayload::SIZE`]).
#[repr(C)]
#[derive(ZeroCopySend, AnyBitPattern, Describe)]
pub struct BenchPayload<const N: usize> {
    pub header: Header,
    /// Which benchmark phase the message belongs to (see [`crate::message::Phase`]).
    pub phase: u64,
    pub bytes: [u8; N],
}

impl<const N: usize> BenchPayload<N> {
    /// Total size in bytes; evaluating it also proves the layout has no padding.
    pub const SIZE: usize = {
        assert!(
            N.is_multiple_of(8),
            "BenchPayload body must be a multiple of 8 bytes"
        );
        assert!(std::mem::size_of::<Self>() == BENCH_PAYLOAD_OVERHEAD + N);
        BENCH_PAYLOAD_OVERHEAD + N
    };
}

impl<const N: usize> std::fmt::Debug for BenchPayload<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BenchPayload")
            .field("header", &self.header)
            .field("phase", &self.phase)
            .field("body_bytes", &N)
            .finish()
    }
}

impl<const N: usize> Payload for BenchPayload<N> {
    const TYPE_NAME: &'static str = "harvest.bench.BenchPayload";
    const VERSION: u32 = 1;

    fn header(&self) -> &Header {
        &self.header
    }
    fn header_mut(&mut self) -> &mut Header {
        &mut self.header
    }

    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        out.reserve(Self::SIZE);
        codec::encode_into(&(self.header, self.phase), out)?;
        out.extend_from_slice(&self.bytes);
        Ok(())
    }

    fn decode_into(bytes: &[u8], dst: &mut Self) -> Result<(), CodecError> {
        let ((header, phase), used): ((Header, u64), usize) = codec::decode_prefix(bytes)?;
        let expected = used + N;
        if bytes.len() != expected {
            return Err(CodecError::Length {
                expected,
                actual: bytes.len(),
            });
        }
        dst.header = header;
        dst.phase = phase;
        dst.bytes.copy_from_slice(&bytes[used..]);
        Ok(())
    }

    fn to_json(&self) -> serde_json::Value {
        serde_json::json!({ "header": self.header, "phase": self.phase, "body_bytes": N })
    }
}

/// A heap-allocated, zero-filled `T` (large payloads never live on the stack).
pub fn zeroed_box<T: Payload>() -> Box<T> {
    harvest_ipc::payload::boxed_zeroed()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip_keeps_every_byte() {
        let mut message = zeroed_box::<BenchPayload<1024>>();
        message.header.msg_seq = 9;
        message.header.publish_ns = 77;
        message.phase = 3;
        for (index, byte) in message.bytes.iter_mut().enumerate() {
            *byte = (index * 7 % 251) as u8;
        }
        let mut encoded = Vec::new();
        message.encode(&mut encoded).expect("encode");
        assert_eq!(encoded.len(), BenchPayload::<1024>::SIZE);
        let mut back = zeroed_box::<BenchPayload<1024>>();
        BenchPayload::decode_into(&encoded, &mut back).expect("decode");
        assert_eq!(back.header, message.header);
        assert_eq!(back.phase, 3);
        assert_eq!(back.bytes, message.bytes);
        assert!(BenchPayload::decode_into(&encoded[..encoded.len() - 1], &mut back).is_err());
    }

    #[test]
    fn sizes_include_the_overhead() {
        assert_eq!(BenchPayload::<32>::SIZE, 64);
        assert_eq!(std::mem::size_of::<BenchPayload<32>>(), 64);
    }
}
