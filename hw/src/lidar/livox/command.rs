//! The general command set of Livox SDK 1 the driver uses (`command_impl.h`,
//! `livox_def.h`, `device_discovery.cpp`, `command_channel.cpp`): ports, command ids and the
//! payloads of discovery, handshake, heartbeat and sampling control, all little-endian.

use std::net::Ipv4Addr;

/// UDP port the host listens on for the devices' discovery broadcasts (`kListenPort`).
pub const DISCOVERY_PORT: u16 = 55000;
/// UDP port of the device's command channel (`command_channel.cpp` sends to 65000).
pub const DEVICE_CMD_PORT: u16 = 65000;
/// The host's command port the SDK hands the first device (`kListenPort + 500 + 1`).
pub const HOST_CMD_PORT: u16 = 55501;
/// The host's point-data port the SDK hands the first device (`kListenPort + 1000 + 1`).
pub const HOST_DATA_PORT: u16 = 56001;

/// Command set 0, general commands.
pub const CMD_SET_GENERAL: u8 = 0;
/// Device -> host message: "I am here" (payload [`Broadcast`]).
pub const CMD_BROADCAST: u8 = 0;
/// Host -> device: where to send data (payload [`Handshake`]); ack: return code.
pub const CMD_HANDSHAKE: u8 = 1;
/// Host -> device at least once a second; ack: [`HeartbeatAck`]. The device drops a host that
/// has been silent for 3 s.
pub const CMD_HEARTBEAT: u8 = 3;
/// Host -> device: payload one byte, 1 start / 0 stop sampling; ack: return code.
pub const CMD_CONTROL_SAMPLE: u8 = 4;
/// Host -> device: forget this host; ack: return code.
pub const CMD_DISCONNECT: u8 = 6;
/// Device -> host message, 10 Hz while abnormal: the error code (u32).
pub const CMD_PUSH_ABNORMAL_STATE: u8 = 7;

/// Device type of the Mid-70 (`kDeviceTypeLidarMid70`).
pub const DEVICE_TYPE_MID70: u8 = 6;

/// Return code of a successful command (first byte of every acknowledgement).
pub const RET_OK: u8 = 0;

/// A device's broadcast code: its serial number, up to 15 ASCII characters, NUL-padded to 16.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BroadcastCode([u8; 16]);

/// Why a broadcast code is not usable.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("broadcast code {code:?}: 1 to 15 printable ASCII characters expected")]
pub struct BadBroadcastCode {
    /// The code as given.
    pub code: String,
}

impl BroadcastCode {
    /// The 15-character broadcast code printed on the device (its serial number and one digit);
    /// refused when it is not 15 ASCII letters and digits.
    pub fn parse(code: &str) -> Result<Self, BadBroadcastCode> {
        let bytes = code.as_bytes();
        if bytes.is_empty() || bytes.len() > 15 || !bytes.iter().all(|b| b.is_ascii_graphic()) {
            return Err(BadBroadcastCode {
                code: code.to_string(),
            });
        }
        let mut raw = [0u8; 16];
        raw[..bytes.len()].copy_from_slice(bytes);
        Ok(Self(raw))
    }

    /// The 16 bytes of the protocol (the code, zero padded).
    pub fn as_bytes(&self) -> &[u8; 16] {
        &self.0
    }

    /// The code up to its first NUL (lossy for non-ASCII bytes from the wire).
    pub fn as_string(&self) -> String {
        let end = self.0.iter().position(|&b| b == 0).unwrap_or(16);
        String::from_utf8_lossy(&self.0[..end]).into_owned()
    }
}

impl std::fmt::Display for BroadcastCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.as_string())
    }
}

/// Why a command payload is malformed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("payload of command {cmd_set}/{cmd_id}: {len} bytes, at least {expected} expected")]
pub struct PayloadTooShort {
    /// Command set of the message.
    pub cmd_set: u8,
    /// Command id of the message.
    pub cmd_id: u8,
    /// Bytes received.
    pub len: usize,
    /// Bytes the message needs.
    pub expected: usize,
}

fn need(cmd_id: u8, payload: &[u8], expected: usize) -> Result<(), PayloadTooShort> {
    if payload.len() < expected {
        return Err(PayloadTooShort {
            cmd_set: CMD_SET_GENERAL,
            cmd_id,
            len: payload.len(),
            expected,
        });
    }
    Ok(())
}

/// Discovery broadcast payload (`BroadcastDeviceInfo` without the IP, which the host takes from
/// the datagram's source): code, device type, 2 reserved bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Broadcast {
    /// The device's broadcast code.
    pub code: BroadcastCode,
    /// Device type code (Mid-70: 6 in the SDK 1 table).
    pub device_type: u8,
}

impl Broadcast {
    /// Encoded length, bytes.
    pub const LEN: usize = 19;

    /// The payload bytes.
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut out = [0u8; Self::LEN];
        out[..16].copy_from_slice(self.code.as_bytes());
        out[16] = self.device_type;
        out
    }

    /// Decodes a payload; too short is refused.
    pub fn decode(payload: &[u8]) -> Result<Self, PayloadTooShort> {
        need(CMD_BROADCAST, payload, Self::LEN)?;
        let mut code = [0u8; 16];
        code.copy_from_slice(&payload[..16]);
        Ok(Self {
            code: BroadcastCode(code),
            device_type: payload[16],
        })
    }
}

/// Handshake request (`HandshakeRequest`): the host's IP (network byte order, as `s_addr`
/// lies in memory), then its data, command and IMU ports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Handshake {
    /// Where the device sends its point and IMU data (the host's address).
    pub host_ip: Ipv4Addr,
    /// Host UDP port for point data.
    pub data_port: u16,
    /// Host UDP port for command acknowledgements.
    pub cmd_port: u16,
    /// Host UDP port for IMU data (0: none).
    pub sensor_port: u16,
}

impl Handshake {
    /// Encoded length, bytes.
    pub const LEN: usize = 10;

    /// The payload bytes.
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut out = [0u8; Self::LEN];
        out[..4].copy_from_slice(&self.host_ip.octets());
        out[4..6].copy_from_slice(&self.data_port.to_le_bytes());
        out[6..8].copy_from_slice(&self.cmd_port.to_le_bytes());
        out[8..10].copy_from_slice(&self.sensor_port.to_le_bytes());
        out
    }

    /// Decodes a payload; too short is refused.
    pub fn decode(payload: &[u8]) -> Result<Self, PayloadTooShort> {
        need(CMD_HANDSHAKE, payload, Self::LEN)?;
        let port = |at: usize| u16::from_le_bytes([payload[at], payload[at + 1]]);
        Ok(Self {
            host_ip: Ipv4Addr::new(payload[0], payload[1], payload[2], payload[3]),
            data_port: port(4),
            cmd_port: port(6),
            sensor_port: port(8),
        })
    }
}

/// Heartbeat acknowledgement (`HeartbeatResponse`): return code, working state (`LidarState`:
/// 0 init, 1 normal, 2 power saving, 3 standby, 4 error), feature, and the error code (or the
/// start-up progress while initialising).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeartbeatAck {
    /// 0 on success.
    pub ret_code: u8,
    /// The device's work state ([`Self::STATE_NORMAL`], [`Self::STATE_ERROR`], ...).
    pub state: u8,
    /// Feature bits (rain/fog suppression and similar).
    pub feature: u8,
    /// The status code (see [`super::error_code`]).
    pub status_code: u32,
}

impl HeartbeatAck {
    /// Encoded length, bytes.
    pub const LEN: usize = 7;
    /// `kLidarStateInit`: `status_code` is the start-up progress, 0-100.
    pub const STATE_INIT: u8 = 0;
    /// Work state: sampling normally.
    pub const STATE_NORMAL: u8 = 1;
    /// Work state: the device reports an error.
    pub const STATE_ERROR: u8 = 4;

    /// The payload bytes.
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut out = [0u8; Self::LEN];
        out[0] = self.ret_code;
        out[1] = self.state;
        out[2] = self.feature;
        out[3..7].copy_from_slice(&self.status_code.to_le_bytes());
        out
    }

    /// Decodes a payload; too short is refused.
    pub fn decode(payload: &[u8]) -> Result<Self, PayloadTooShort> {
        need(CMD_HEARTBEAT, payload, Self::LEN)?;
        Ok(Self {
            ret_code: payload[0],
            state: payload[1],
            feature: payload[2],
            status_code: u32::from_le_bytes([payload[3], payload[4], payload[5], payload[6]]),
        })
    }
}

/// The return code of an acknowledgement (its first byte).
pub fn ret_code(cmd_id: u8, payload: &[u8]) -> Result<u8, PayloadTooShort> {
    need(cmd_id, payload, 1)?;
    Ok(payload[0])
}

/// What a host may send on the device's command port (what the fake device decodes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HostCommand {
    /// The host introduces itself (its address and ports).
    Handshake(Handshake),
    /// The host's periodic keep-alive.
    Heartbeat,
    /// Start or stop sampling.
    ControlSample {
        /// True: start; false: stop.
        start: bool,
    },
    /// The host leaves.
    Disconnect,
    /// Any other command set or id (the device answers it with a failure code).
    Other {
        /// Command set.
        cmd_set: u8,
        /// Command id.
        cmd_id: u8,
    },
}

impl HostCommand {
    /// Decodes a command; a payload too short for its command is refused.
    pub fn decode(cmd_set: u8, cmd_id: u8, payload: &[u8]) -> Result<Self, PayloadTooShort> {
        if cmd_set != CMD_SET_GENERAL {
            return Ok(Self::Other { cmd_set, cmd_id });
        }
        Ok(match cmd_id {
            CMD_HANDSHAKE => Self::Handshake(Handshake::decode(payload)?),
            CMD_HEARTBEAT => Self::Heartbeat,
            CMD_CONTROL_SAMPLE => Self::ControlSample {
                start: ret_code(cmd_id, payload)? != 0,
            },
            CMD_DISCONNECT => Self::Disconnect,
            _ => Self::Other { cmd_set, cmd_id },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payloads_round_trip() {
        let code = BroadcastCode::parse("3GGDJ6K00100101").expect("code");
        let broadcast = Broadcast {
            code,
            device_type: DEVICE_TYPE_MID70,
        };
        assert_eq!(Broadcast::decode(&broadcast.encode()), Ok(broadcast));
        assert_eq!(code.as_string(), "3GGDJ6K00100101");
        let handshake = Handshake {
            host_ip: Ipv4Addr::new(192, 168, 1, 50),
            data_port: 56001,
            cmd_port: 55501,
            sensor_port: 56001,
        };
        let bytes = handshake.encode();
        assert_eq!(&bytes[..4], &[192, 168, 1, 50]);
        assert_eq!(&bytes[4..6], &56001u16.to_le_bytes());
        assert_eq!(Handshake::decode(&bytes), Ok(handshake));
        let ack = HeartbeatAck {
            ret_code: 0,
            state: 1,
            feature: 0,
            status_code: 0x8000_0001,
        };
        assert_eq!(HeartbeatAck::decode(&ack.encode()), Ok(ack));
    }

    #[test]
    fn broadcast_codes_are_checked() {
        assert!(BroadcastCode::parse("").is_err());
        assert!(BroadcastCode::parse("0123456789ABCDEF").is_err());
        assert!(BroadcastCode::parse("with space").is_err());
    }

    #[test]
    fn short_payloads_are_refused() {
        assert!(Handshake::decode(&[0; 9]).is_err());
        assert!(HeartbeatAck::decode(&[0; 6]).is_err());
        assert!(HostCommand::decode(0, CMD_CONTROL_SAMPLE, &[]).is_err());
        assert_eq!(
            HostCommand::decode(0, CMD_CONTROL_SAMPLE, &[1]),
            Ok(HostCommand::ControlSample { start: true })
        );
    }
}
