//! Property tests of the Livox SDK 1 decoders of outside bytes (the control frame and the
//! point-data packet): any datagram decodes or is refused without panicking, every encodable
//! frame and packet round-trips, any single-bit corruption of a control frame is refused, and
//! every truncation of a point packet is.

use harvest_hw::lidar::livox::command::{Broadcast, Handshake, HeartbeatAck, HostCommand};
use harvest_hw::lidar::livox::frame::{Frame, PacketType, decode_frame, encode_frame};
use harvest_hw::lidar::livox::point_packet::{
    DataType, PacketError, PointPacketHeader, RawReturn, TimestampType, decode_point_packet,
    encode_point_packet,
};
use proptest::prelude::*;

/// Cases per property (each is one or two kilobytes of parsing: microseconds).
const CASES: u32 = 512;

fn packet_type() -> impl Strategy<Value = PacketType> {
    prop_oneof![
        Just(PacketType::Command),
        Just(PacketType::Ack),
        Just(PacketType::Message)
    ]
}

fn raw_return() -> impl Strategy<Value = RawReturn> {
    (
        any::<i32>(),
        any::<i32>(),
        any::<i32>(),
        any::<u8>(),
        any::<u8>(),
    )
        .prop_map(|(x_mm, y_mm, z_mm, reflectivity, tag)| RawReturn {
            x_mm,
            y_mm,
            z_mm,
            reflectivity,
            tag,
        })
}

fn data_type() -> impl Strategy<Value = DataType> {
    prop_oneof![
        Just(DataType::ExtendedCartesian),
        Just(DataType::DualExtendedCartesian)
    ]
}

fn timestamp_type() -> impl Strategy<Value = TimestampType> {
    prop_oneof![
        Just(TimestampType::NoSync),
        Just(TimestampType::Ptp),
        Just(TimestampType::Pps)
    ]
}

fn encoded_packet() -> impl Strategy<Value = (PointPacketHeader, Vec<RawReturn>, Vec<u8>)> {
    (
        data_type(),
        timestamp_type(),
        any::<u64>(),
        any::<u32>(),
        prop::collection::vec(raw_return(), 96),
    )
        .prop_map(|(data_type, timestamp_type, stamp, status_code, returns)| {
            let header = PointPacketHeader {
                slot: 1,
                lidar_id: 1,
                status_code,
                timestamp_type,
                data_type,
                timestamp: stamp.to_le_bytes(),
            };
            let mut out = Vec::new();
            encode_point_packet(&header, &returns, &mut out).expect("encode");
            (header, returns, out)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    #[test]
    fn any_datagram_is_decoded_or_refused(bytes in prop::collection::vec(any::<u8>(), 0..1600)) {
        if let Ok(frame) = decode_frame(&bytes) {
            let _ = HostCommand::decode(frame.cmd_set, frame.cmd_id, frame.payload);
            let _ = Broadcast::decode(frame.payload);
            let _ = Handshake::decode(frame.payload);
            let _ = HeartbeatAck::decode(frame.payload);
        }
        if let Ok(packet) = decode_point_packet(&bytes) {
            prop_assert_eq!(packet.returns().count(), 96);
            prop_assert!(packet.header.first_firing_ns().is_ok());
        }
    }

    #[test]
    fn a_point_packet_shaped_datagram_is_decoded_or_refused(
        mut bytes in prop::collection::vec(any::<u8>(), 1362),
        data_code in 0u8..10,
        stamp_code in 0u8..6,
    ) {
        // Valid version and (often) valid types, so the decoder goes past the header checks.
        bytes[0] = 5;
        bytes[8] = stamp_code;
        bytes[9] = data_code;
        match decode_point_packet(&bytes) {
            Ok(packet) => prop_assert_eq!(packet.returns().count(), 96),
            Err(error) => prop_assert!(!error.to_string().is_empty()),
        }
    }

    #[test]
    fn frames_round_trip(
        packet_type in packet_type(),
        seq in any::<u16>(),
        cmd_set in any::<u8>(),
        cmd_id in any::<u8>(),
        payload in prop::collection::vec(any::<u8>(), 0..200),
    ) {
        let frame = Frame { packet_type, seq, cmd_set, cmd_id, payload: &payload };
        let mut out = Vec::new();
        encode_frame(&frame, &mut out).expect("encode");
        prop_assert_eq!(decode_frame(&out), Ok(frame));
    }

    #[test]
    fn any_single_bit_flip_of_a_frame_is_refused(
        packet_type in packet_type(),
        seq in any::<u16>(),
        payload in prop::collection::vec(any::<u8>(), 0..64),
        bit in any::<prop::sample::Index>(),
    ) {
        let frame = Frame { packet_type, seq, cmd_set: 0, cmd_id: 3, payload: &payload };
        let mut out = Vec::new();
        encode_frame(&frame, &mut out).expect("encode");
        let bit = bit.index(out.len() * 8);
        out[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(decode_frame(&out).is_err(), "bit {} flipped and accepted", bit);
    }

    #[test]
    fn point_packets_round_trip_and_every_truncation_is_refused(
        (header, returns, bytes) in encoded_packet(),
        cut in any::<prop::sample::Index>(),
    ) {
        let packet = decode_point_packet(&bytes).expect("decode");
        prop_assert_eq!(packet.header, header);
        prop_assert!(packet.returns().eq(returns.iter().copied()));
        let cut = cut.index(bytes.len());
        let truncated = decode_point_packet(&bytes[..cut]);
        prop_assert!(
            matches!(truncated, Err(PacketError::Truncated { .. })),
            "cut at {}: {:?}", cut, truncated
        );
    }
}
