//! The Livox SDK 1 control frame (`sdk_core/src/comm/sdk_protocol.{h,cpp}`), one per UDP
//! datagram on the command ports, all fields little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 0 | start of frame, 0xAA |
//! | 1 | protocol version, 1 (`kSdkVer0`) |
//! | 2-3 | length of the whole frame, bytes |
//! | 4 | packet type: 0 command, 1 acknowledgement, 2 message |
//! | 5-6 | sequence number |
//! | 7-8 | CRC-16 of bytes 0-6 ([`crc::crc16`]) |
//! | 9 | command set |
//! | 10 | command id |
//! | 11.. | payload |
//! | last 4 | CRC-32 of every byte before it ([`crc::crc32`]) |

use super::crc;

/// Start-of-frame byte.
pub const SOF: u8 = 0xAA;
/// The protocol version the SDK writes (`kSdkVer0` = 1).
pub const PROTOCOL_VERSION: u8 = 1;
/// Bytes before the command set: start, version, length, type, sequence, CRC-16.
pub const PREAMBLE_LEN: usize = 9;
/// Bytes of a frame without payload (preamble, command set and id, CRC-32).
pub const WRAPPER_LEN: usize = PREAMBLE_LEN + 2 + 4;
/// Largest frame the SDK sends or accepts (`kMaxCommandBufferSize`).
pub const MAX_FRAME_LEN: usize = 1536;

/// What a frame is (byte 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketType {
    /// A request that wants an acknowledgement.
    Command,
    /// The answer to a command (same sequence number, command set and id).
    Ack,
    /// Unsolicited: the device's discovery broadcast, its abnormal-state push.
    Message,
}

impl PacketType {
    /// The code on the wire.
    pub fn code(self) -> u8 {
        match self {
            Self::Command => 0,
            Self::Ack => 1,
            Self::Message => 2,
        }
    }

    /// The packet type of a wire code; `None` for an unknown one.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::Command),
            1 => Some(Self::Ack),
            2 => Some(Self::Message),
            _ => None,
        }
    }
}

/// A decoded frame borrowing its payload from the datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Command, acknowledgement or message.
    pub packet_type: PacketType,
    /// Sequence number, echoed in the acknowledgement.
    pub seq: u16,
    /// Command set.
    pub cmd_set: u8,
    /// Command id within the set.
    pub cmd_id: u8,
    /// The bytes after the command id, before the checksum.
    pub payload: &'a [u8],
}

/// Why a datagram is not a control frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Shorter than a frame without payload.
    #[error("control frame of {len} bytes is shorter than the {WRAPPER_LEN}-byte minimum")]
    Truncated {
        /// Bytes received.
        len: usize,
    },
    /// The first byte is not 0xAA.
    #[error("control frame starts with {byte:#04x}, not 0xAA")]
    BadStart {
        /// The first byte.
        byte: u8,
    },
    /// A protocol version other than 1.
    #[error("control frame version {version}, expected {PROTOCOL_VERSION}")]
    BadVersion {
        /// The version byte.
        version: u8,
    },
    /// The length field disagrees with the datagram.
    #[error("control frame declares {declared} bytes, datagram holds {received}")]
    BadLength {
        /// Length the frame declares, bytes.
        declared: usize,
        /// Bytes the datagram holds.
        received: usize,
    },
    /// The preamble's CRC-16 does not match.
    #[error("control frame preamble CRC-16 mismatch")]
    PreambleCrc,
    /// The frame's CRC-32 does not match.
    #[error("control frame CRC-32 mismatch")]
    FrameCrc,
    /// Packet type outside 0-2.
    #[error("control frame packet type {code} unknown")]
    UnknownPacketType {
        /// The packet type byte.
        code: u8,
    },
}

/// Decodes one datagram as a control frame, checking start byte, version, length and both CRCs.
pub fn decode_frame(datagram: &[u8]) -> Result<Frame<'_>, FrameError> {
    if datagram.len() < WRAPPER_LEN {
        return Err(FrameError::Truncated {
            len: datagram.len(),
        });
    }
    if datagram[0] != SOF {
        return Err(FrameError::BadStart { byte: datagram[0] });
    }
    if crc::crc16(&datagram[..PREAMBLE_LEN]) != 0 {
        return Err(FrameError::PreambleCrc);
    }
    if datagram[1] != PROTOCOL_VERSION {
        return Err(FrameError::BadVersion {
            version: datagram[1],
        });
    }
    let declared = usize::from(u16::from_le_bytes([datagram[2], datagram[3]]));
    if declared != datagram.len() {
        return Err(FrameError::BadLength {
            declared,
            received: datagram.len(),
        });
    }
    let (body, crc_bytes) = datagram.split_at(declared - 4);
    let stored = u32::from_le_bytes([crc_bytes[0], crc_bytes[1], crc_bytes[2], crc_bytes[3]]);
    if crc::crc32(body) != stored {
        return Err(FrameError::FrameCrc);
    }
    let packet_type = PacketType::from_code(datagram[4])
        .ok_or(FrameError::UnknownPacketType { code: datagram[4] })?;
    Ok(Frame {
        packet_type,
        seq: u16::from_le_bytes([datagram[5], datagram[6]]),
        cmd_set: datagram[9],
        cmd_id: datagram[10],
        payload: &body[PREAMBLE_LEN + 2..],
    })
}

/// Why a frame cannot be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("control frame payload of {payload_len} bytes exceeds the {MAX_FRAME_LEN}-byte frame")]
pub struct FrameTooLong {
    /// The payload's length, bytes.
    pub payload_len: usize,
}

/// Writes `frame` as one datagram into `out` (replacing its contents).
pub fn encode_frame(frame: &Frame<'_>, out: &mut Vec<u8>) -> Result<(), FrameTooLong> {
    let len = WRAPPER_LEN + frame.payload.len();
    if len > MAX_FRAME_LEN {
        return Err(FrameTooLong {
            payload_len: frame.payload.len(),
        });
    }
    out.clear();
    out.push(SOF);
    out.push(PROTOCOL_VERSION);
    out.extend_from_slice(&(len as u16).to_le_bytes());
    out.push(frame.packet_type.code());
    out.extend_from_slice(&frame.seq.to_le_bytes());
    let preamble_crc = crc::crc16(&out[..PREAMBLE_LEN - 2]);
    out.extend_from_slice(&preamble_crc.to_le_bytes());
    out.push(frame.cmd_set);
    out.push(frame.cmd_id);
    out.extend_from_slice(frame.payload);
    let frame_crc = crc::crc32(out);
    out.extend_from_slice(&frame_crc.to_le_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heartbeat(seq: u16) -> Vec<u8> {
        let mut out = Vec::new();
        encode_frame(
            &Frame {
                packet_type: PacketType::Command,
                seq,
                cmd_set: 0,
                cmd_id: 3,
                payload: &[],
            },
            &mut out,
        )
        .expect("encode");
        out
    }

    #[test]
    fn round_trip_keeps_every_field() {
        let payload = [1, 2, 3, 4, 5];
        let frame = Frame {
            packet_type: PacketType::Ack,
            seq: 0xBEEF,
            cmd_set: 1,
            cmd_id: 0x0a,
            payload: &payload,
        };
        let mut out = Vec::new();
        encode_frame(&frame, &mut out).expect("encode");
        assert_eq!(out.len(), WRAPPER_LEN + payload.len());
        assert_eq!(decode_frame(&out), Ok(frame));
    }

    #[test]
    fn each_damage_is_named() {
        let good = heartbeat(7);
        assert_eq!(
            decode_frame(&good[..10]),
            Err(FrameError::Truncated { len: 10 })
        );
        let mut bad = good.clone();
        bad[0] = 0x55;
        assert_eq!(decode_frame(&bad), Err(FrameError::BadStart { byte: 0x55 }));
        let mut bad = good.clone();
        bad[5] ^= 1;
        assert_eq!(decode_frame(&bad), Err(FrameError::PreambleCrc));
        let mut bad = good.clone();
        bad[10] ^= 0x80;
        assert_eq!(decode_frame(&bad), Err(FrameError::FrameCrc));
        let mut longer = good.clone();
        longer.push(0);
        assert_eq!(
            decode_frame(&longer),
            Err(FrameError::BadLength {
                declared: good.len(),
                received: good.len() + 1
            })
        );
    }

    #[test]
    fn too_long_a_payload_is_refused() {
        let payload = vec![0u8; MAX_FRAME_LEN];
        let frame = Frame {
            packet_type: PacketType::Command,
            seq: 1,
            cmd_set: 0,
            cmd_id: 0,
            payload: &payload,
        };
        assert!(encode_frame(&frame, &mut Vec::new()).is_err());
    }
}
