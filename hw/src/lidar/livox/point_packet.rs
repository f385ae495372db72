//! Point-data packets of Livox SDK 1 (`LivoxEthPacket` in `livox_def.h`): one UDP datagram on
//! the host's data port, no framing and no checksum, little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 0 | packet protocol version, 5 |
//! | 1 | slot (hub port; 1 for a LiDAR on its own) |
//! | 2 | LiDAR id |
//! | 3 | reserved |
//! | 4-7 | error code ([`super::error_code::StatusCode`]) |
//! | 8 | timestamp type ([`TimestampType`]) |
//! | 9 | data type ([`DataType`]) |
//! | 10-17 | timestamp of the first point |
//! | 18.. | points |
//!
//! The Mid-70 fires every 10 us; a packet's points are consecutive firings, so the first point's
//! timestamp plus 10 us per firing stamps each of them, and a gap between the end of one packet
//! and the start of the next tells lost packets. A firing without a return reports (0, 0, 0).

/// Version byte of the point-data packets the SDK 1 devices send.
pub const POINT_PACKET_VERSION: u8 = 5;
/// Bytes before the points.
pub const HEADER_LEN: usize = 18;
/// Time between two firings, nanoseconds (100,000 per second).
pub const FIRING_PERIOD_NS: u64 = 10_000;

/// The point formats the driver accepts (the Mid-70's Cartesian outputs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataType {
    /// `kExtendCartesian` (2): 96 firings of int32 x, y, z (mm), reflectivity, tag: 14 bytes.
    ExtendedCartesian,
    /// `kDualExtendCartesian` (4): 48 firings with two returns each: 28 bytes.
    DualExtendedCartesian,
}

impl DataType {
    /// The code on the wire.
    pub fn code(self) -> u8 {
        match self {
            Self::ExtendedCartesian => 2,
            Self::DualExtendedCartesian => 4,
        }
    }

    /// The data type of a wire code; `None` for one the driver does not decode.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            2 => Some(Self::ExtendedCartesian),
            4 => Some(Self::DualExtendedCartesian),
            _ => None,
        }
    }

    /// Firings in one packet.
    pub fn firings(self) -> usize {
        match self {
            Self::ExtendedCartesian => 96,
            Self::DualExtendedCartesian => 48,
        }
    }

    /// Returns per firing.
    pub fn returns_per_firing(self) -> usize {
        match self {
            Self::ExtendedCartesian => 1,
            Self::DualExtendedCartesian => 2,
        }
    }

    /// Length of the whole packet, bytes (1362 for both).
    pub fn packet_len(self) -> usize {
        HEADER_LEN + self.firings() * self.returns_per_firing() * RETURN_LEN
    }

    /// Device time one packet covers, nanoseconds.
    pub fn packet_span_ns(self) -> u64 {
        self.firings() as u64 * FIRING_PERIOD_NS
    }
}

/// Bytes of one Cartesian return: x, y, z (i32 mm), reflectivity, tag.
pub const RETURN_LEN: usize = 14;

/// How the device's clock is synchronised (`TimestampType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimestampType {
    /// 0: no synchronisation, nanoseconds since the device started.
    NoSync,
    /// 1: IEEE 1588 PTP, nanoseconds of the PTP master's time.
    Ptp,
    /// 3: PPS plus GPS: UTC as year (since 2000), month, day, hour, then u32 microseconds
    /// within the hour.
    PpsGps,
    /// 4: PPS only, nanoseconds (the device aligns its counter to the pulse).
    Pps,
}

impl TimestampType {
    /// The code on the wire.
    pub fn code(self) -> u8 {
        match self {
            Self::NoSync => 0,
            Self::Ptp => 1,
            Self::PpsGps => 3,
            Self::Pps => 4,
        }
    }

    /// The timestamp type of a wire code; `None` for an unknown one.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::NoSync),
            1 => Some(Self::Ptp),
            3 => Some(Self::PpsGps),
            4 => Some(Self::Pps),
            _ => None,
        }
    }
}

/// One return as the device encodes it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RawReturn {
    /// Position in the LiDAR frame, millimetres.
    pub x_mm: i32,
    /// Position in the LiDAR frame, millimetres.
    pub y_mm: i32,
    /// Position in the LiDAR frame, millimetres.
    pub z_mm: i32,
    /// Reflectivity, 0-255 (0-150 diffuse, 151-255 retro-reflective).
    pub reflectivity: u8,
    /// Return tag bits (confidence of spatial, intensity and return position).
    pub tag: u8,
}

impl RawReturn {
    /// A firing without a return is reported at the origin.
    pub fn is_empty(&self) -> bool {
        self.x_mm == 0 && self.y_mm == 0 && self.z_mm == 0
    }

    fn read(bytes: &[u8]) -> Self {
        let int = |at: usize| {
            i32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        Self {
            x_mm: int(0),
            y_mm: int(4),
            z_mm: int(8),
            reflectivity: bytes[12],
            tag: bytes[13],
        }
    }

    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.x_mm.to_le_bytes());
        out.extend_from_slice(&self.y_mm.to_le_bytes());
        out.extend_from_slice(&self.z_mm.to_le_bytes());
        out.push(self.reflectivity);
        out.push(self.tag);
    }
}

/// The header fields of a point packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PointPacketHeader {
    /// The slot (hub port) the device sits on; 1 without a hub.
    pub slot: u8,
    /// The LiDAR unit within the device (1 for the Mid-70).
    pub lidar_id: u8,
    /// The device status code (see [`super::error_code`]).
    pub status_code: u32,
    /// How `timestamp` is to be read.
    pub timestamp_type: TimestampType,
    /// How the returns are encoded.
    pub data_type: DataType,
    /// The raw 8 timestamp bytes (see [`TimestampType`] for their meaning).
    pub timestamp: [u8; 8],
}

impl PointPacketHeader {
    /// The first firing's device time, nanoseconds (since the device's epoch for the
    /// timestamp type: its start, the PTP epoch, the PPS counter, or 2000-01-01 UTC for GPS).
    pub fn first_firing_ns(&self) -> Result<u64, PacketError> {
        match self.timestamp_type {
            TimestampType::NoSync | TimestampType::Ptp | TimestampType::Pps => {
                Ok(u64::from_le_bytes(self.timestamp))
            }
            TimestampType::PpsGps => utc_ns(self.timestamp),
        }
    }
}

/// Nanoseconds since 2000-01-01 UTC of the GPS timestamp layout.
fn utc_ns(bytes: [u8; 8]) -> Result<u64, PacketError> {
    let [year, month, day, hour, a, b, c, d] = bytes;
    let microsecond = u32::from_le_bytes([a, b, c, d]);
    let days_in_month = [31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31];
    let leap = |y: u64| y.is_multiple_of(4) && (!y.is_multiple_of(100) || y.is_multiple_of(400));
    let full_year = 2000 + u64::from(year);
    if !(1..=12).contains(&month)
        || day == 0
        || hour > 23
        || u64::from(microsecond) >= 3_600_000_000
    {
        return Err(PacketError::BadTimestamp);
    }
    let month_index = usize::from(month - 1);
    let month_days = days_in_month[month_index] + u8::from(month == 2 && leap(full_year));
    if day > month_days {
        return Err(PacketError::BadTimestamp);
    }
    let mut days: u64 = (2000..full_year).map(|y| 365 + u64::from(leap(y))).sum();
    days += days_in_month[..month_index]
        .iter()
        .map(|&d| u64::from(d))
        .sum::<u64>();
    if month > 2 && leap(full_year) {
        days += 1;
    }
    days += u64::from(day - 1);
    let hours = days * 24 + u64::from(hour);
    Ok(hours * 3_600_000_000_000 + u64::from(microsecond) * 1_000)
}

/// A decoded packet borrowing its points from the datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PointPacket<'a> {
    /// The header fields.
    pub header: PointPacketHeader,
    body: &'a [u8],
}

impl PointPacket<'_> {
    /// The returns in firing order (two per firing for dual returns); the firing index of
    /// return `k` is `k / returns_per_firing`.
    pub fn returns(&self) -> impl Iterator<Item = RawReturn> + '_ {
        self.body.chunks_exact(RETURN_LEN).map(RawReturn::read)
    }
}

/// Why a datagram on the data port is not a usable point packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// Shorter than its header or than its data type's points.
    #[error("point packet of {len} bytes is truncated ({expected} expected)")]
    Truncated {
        /// Bytes received.
        len: usize,
        /// Bytes its header and data type need.
        expected: usize,
    },
    /// Longer than its data type's points.
    #[error("point packet of {len} bytes is longer than the {expected} its data type holds")]
    BadLength {
        /// Bytes received.
        len: usize,
        /// Bytes its data type holds.
        expected: usize,
    },
    /// A packet version other than 5.
    #[error("point packet version {version}, expected {POINT_PACKET_VERSION}")]
    BadVersion {
        /// The version byte.
        version: u8,
    },
    /// A data type the driver does not decode (spherical, IMU, triple return, unknown).
    #[error("point packet data type {code} not handled (2 or 4 expected)")]
    UnknownDataType {
        /// The data type byte.
        code: u8,
    },
    /// A timestamp type outside 0, 1, 3, 4.
    #[error("point packet timestamp type {code} unknown")]
    UnknownTimestampType {
        /// The timestamp type byte.
        code: u8,
    },
    /// A GPS timestamp that is not a date.
    #[error("point packet UTC timestamp is not a valid date")]
    BadTimestamp,
}

/// Decodes one datagram of the data port.
pub fn decode_point_packet(datagram: &[u8]) -> Result<PointPacket<'_>, PacketError> {
    if datagram.len() < HEADER_LEN {
        return Err(PacketError::Truncated {
            len: datagram.len(),
            expected: HEADER_LEN,
        });
    }
    if datagram[0] != POINT_PACKET_VERSION {
        return Err(PacketError::BadVersion {
            version: datagram[0],
        });
    }
    let data_type = DataType::from_code(datagram[9])
        .ok_or(PacketError::UnknownDataType { code: datagram[9] })?;
    let timestamp_type = TimestampType::from_code(datagram[8])
        .ok_or(PacketError::UnknownTimestampType { code: datagram[8] })?;
    let expected = data_type.packet_len();
    if datagram.len() < expected {
        return Err(PacketError::Truncated {
            len: datagram.len(),
            expected,
        });
    }
    if datagram.len() > expected {
        return Err(PacketError::BadLength {
            len: datagram.len(),
            expected,
        });
    }
    let mut timestamp = [0u8; 8];
    timestamp.copy_from_slice(&datagram[10..18]);
    let header = PointPacketHeader {
        slot: datagram[1],
        lidar_id: datagram[2],
        status_code: u32::from_le_bytes([datagram[4], datagram[5], datagram[6], datagram[7]]),
        timestamp_type,
        data_type,
        timestamp,
    };
    header.first_firing_ns()?;
    Ok(PointPacket {
        header,
        body: &datagram[HEADER_LEN..],
    })
}

/// Why a packet cannot be encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{given} returns given, a {data_type:?} packet holds {expected}")]
pub struct WrongReturnCount {
    /// The data type.
    pub data_type: DataType,
    /// Returns given.
    pub given: usize,
    /// Returns a packet of that type holds.
    pub expected: usize,
}

/// Writes a packet into `out` (replacing its contents): `returns` in firing order, exactly
/// `firings * returns_per_firing` of them.
pub fn encode_point_packet(
    header: &PointPacketHeader,
    returns: &[RawReturn],
    out: &mut Vec<u8>,
) -> Result<(), WrongReturnCount> {
    let expected = header.data_type.firings() * header.data_type.returns_per_firing();
    if returns.len() != expected {
        return Err(WrongReturnCount {
            data_type: header.data_type,
            given: returns.len(),
            expected,
        });
    }
    out.clear();
    out.extend_from_slice(&[POINT_PACKET_VERSION, header.slot, header.lidar_id, 0]);
    out.extend_from_slice(&header.status_code.to_le_bytes());
    out.push(header.timestamp_type.code());
    out.push(header.data_type.code());
    out.extend_from_slice(&header.timestamp);
    for value in returns {
        value.write(out);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(data_type: DataType, first_ns: u64) -> PointPacketHeader {
        PointPacketHeader {
            slot: 1,
            lidar_id: 1,
            status_code: 0,
            timestamp_type: TimestampType::NoSync,
            data_type,
            timestamp: first_ns.to_le_bytes(),
        }
    }

    #[test]
    fn both_data_types_round_trip() {
        for data_type in [DataType::ExtendedCartesian, DataType::DualExtendedCartesian] {
            let returns: Vec<RawReturn> = (0..96)
                .map(|k| RawReturn {
                    x_mm: 1000 + k,
                    y_mm: -k,
                    z_mm: 7,
                    reflectivity: k as u8,
                    tag: 0,
                })
                .collect();
            let mut out = Vec::new();
            encode_point_packet(&header(data_type, 123_456), &returns, &mut out).expect("encode");
            assert_eq!(out.len(), 1362);
            let packet = decode_point_packet(&out).expect("decode");
            assert_eq!(packet.header, header(data_type, 123_456));
            assert_eq!(packet.header.first_firing_ns(), Ok(123_456));
            assert!(packet.returns().eq(returns.iter().copied()));
        }
    }

    #[test]
    fn damage_is_named() {
        let mut out = Vec::new();
        let returns = vec![RawReturn::default(); 96];
        encode_point_packet(&header(DataType::ExtendedCartesian, 0), &returns, &mut out)
            .expect("encode");
        assert!(matches!(
            decode_point_packet(&out[..100]),
            Err(PacketError::Truncated { len: 100, .. })
        ));
        let mut bad = out.clone();
        bad[0] = 4;
        assert_eq!(
            decode_point_packet(&bad),
            Err(PacketError::BadVersion { version: 4 })
        );
        let mut bad = out.clone();
        bad[9] = 6;
        assert_eq!(
            decode_point_packet(&bad),
            Err(PacketError::UnknownDataType { code: 6 })
        );
        let mut bad = out.clone();
        bad[8] = 2;
        assert_eq!(
            decode_point_packet(&bad),
            Err(PacketError::UnknownTimestampType { code: 2 })
        );
        let mut bad = out;
        bad.push(0);
        assert!(matches!(
            decode_point_packet(&bad),
            Err(PacketError::BadLength { .. })
        ));
    }

    #[test]
    fn gps_timestamps_count_from_2000() {
        // 2001-03-01 02:00 plus 5 us: 366 (2000 is a leap year) + 31 + 28 days, 2 hours.
        let mut stamp = [1, 3, 1, 2, 0, 0, 0, 0];
        stamp[4..].copy_from_slice(&5u32.to_le_bytes());
        let days = 366 + 31 + 28;
        let expected = (days * 24 + 2) * 3_600_000_000_000u64 + 5_000;
        assert_eq!(utc_ns(stamp), Ok(expected));
        assert_eq!(
            utc_ns([0, 2, 30, 0, 0, 0, 0, 0]),
            Err(PacketError::BadTimestamp)
        );
        // 2000 is a leap year: 29 February exists.
        assert!(utc_ns([0, 2, 29, 0, 0, 0, 0, 0]).is_ok());
    }
}
