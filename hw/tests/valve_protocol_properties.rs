//! Property tests of the valve board's serial decoders: the line assembler
//! and the frame, reply, fault and request decoders take any byte stream without panicking,
//! never hand out a line the protocol forbids, recover every well-formed frame from between
//! any noise, and refuse any single-bit corruption of a frame.

use harvest_hw::valve_board::line_assembler::LineAssembler;
use harvest_hw::valve_board::protocol::{
    BoardMessage, MAX_FRAME_LEN, Reply, Request, Status, decode_board_message, decode_frame,
    decode_request, encode_fault, encode_reply, encode_request,
};
use harvest_hw::valve_board::types::{
    BoardFault, PressureReadings, PressureSensor, ValveId, ValveState, ValveStates,
};
use proptest::prelude::*;

/// Cases per property (each case is a few hundred bytes of parsing: microseconds).
const CASES: u32 = 512;

fn valve_state() -> impl Strategy<Value = ValveState> {
    prop_oneof![
        Just(ValveState::Closed),
        Just(ValveState::Open),
        Just(ValveState::Opening),
        Just(ValveState::Closing),
        Just(ValveState::Stuck),
    ]
}

fn reply() -> impl Strategy<Value = Reply> {
    prop_oneof![
        any::<u32>().prop_map(|uptime_ms| Reply::Pong { uptime_ms }),
        (1u8..=4, any::<bool>()).prop_map(|(v, open)| Reply::SetAck {
            valve: ValveId(v),
            open
        }),
        prop::array::uniform4(valve_state()).prop_map(|s| Reply::Valves(ValveStates(s))),
        prop::array::uniform3(-99_999i32..=99_999)
            .prop_map(|p| Reply::Pressures(PressureReadings::from_array(p.map(|v| v as f32)))),
        Just(Reply::ClosedAll),
        prop_oneof![
            Just(Status::Syntax),
            Just(Status::Range),
            Just(Status::Fault)
        ]
        .prop_map(Reply::Error),
    ]
}

fn fault() -> impl Strategy<Value = BoardFault> {
    prop_oneof![
        (1u8..=4).prop_map(|v| BoardFault::ValveStuck(ValveId(v))),
        (1u8..=3).prop_map(|s| BoardFault::SensorFault(
            PressureSensor::from_number(s).expect("sensor 1..=3")
        )),
        Just(BoardFault::SupplyLow),
        Just(BoardFault::BoardReset),
    ]
}

/// A board line: a reply to `seq` or a fault.
fn board_message() -> impl Strategy<Value = BoardMessage> {
    prop_oneof![
        (any::<u8>(), reply()).prop_map(|(seq, reply)| BoardMessage::Reply { seq, reply }),
        fault().prop_map(BoardMessage::Fault),
    ]
}

fn encode_message(message: &BoardMessage, out: &mut Vec<u8>) {
    match message {
        BoardMessage::Reply { seq, reply } => encode_reply(*seq, reply, out),
        BoardMessage::Fault(fault) => encode_fault(fault, out),
    }
}

fn request() -> impl Strategy<Value = Request> {
    prop_oneof![
        Just(Request::Ping),
        (1u8..=4, any::<bool>()).prop_map(|(v, open)| Request::Set {
            valve: ValveId(v),
            open
        }),
        Just(Request::Valves),
        Just(Request::Pressures),
        Just(Request::CloseAll),
    ]
}

/// Noise on the line: arbitrary bytes, weighted towards the protocol's own characters.
fn noise(max: usize) -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(
        prop_oneof![
            4 => any::<u8>(),
            1 => prop::sample::select(b"$*\n\r U0123456789ABCDEFOKERRPRESVALVES".to_vec()),
        ],
        0..max,
    )
}

/// Feeds `bytes` to an assembler and decodes every completed line as the host driver does
/// (board messages) and as the fake board does (requests). Returns the board messages.
fn decode_stream(bytes: &[u8]) -> Result<Vec<BoardMessage>, TestCaseError> {
    let mut assembler = LineAssembler::new();
    let mut messages = Vec::new();
    for &byte in bytes {
        let Some(event) = assembler.push(byte) else {
            continue;
        };
        let Ok(line) = event else {
            let _ = event.map_err(|error| error.to_string());
            continue;
        };
        prop_assert!(line.len() <= MAX_FRAME_LEN, "line of {} bytes", line.len());
        prop_assert!(line.iter().all(|b| (0x20..=0x7E).contains(b)), "{line:?}");
        match decode_frame(line) {
            Ok(frame) => {
                if let Ok(request) = decode_request(frame.body) {
                    let _ = request.verb();
                }
                match decode_board_message(&frame) {
                    Ok(message) => messages.push(message),
                    Err(error) => prop_assert!(!error.to_string().is_empty()),
                }
            }
            Err(error) => prop_assert!(!error.to_string().is_empty()),
        }
    }
    prop_assert!(assembler.discarded_bytes() <= bytes.len() as u64);
    Ok(messages)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Any byte stream: no panic, only printable lines within the length limit.
    #[test]
    fn any_byte_stream_is_framed_and_decoded_without_panic(bytes in noise(600)) {
        decode_stream(&bytes)?;
    }

    /// Well-formed board lines between arbitrary noise are all recovered, in order (noise
    /// may at most add lines of its own, which a CRC-8 lets through once in 256).
    #[test]
    fn every_frame_between_noise_is_recovered(
        parts in prop::collection::vec((noise(40), board_message()), 1..8),
        tail in noise(40),
    ) {
        let mut stream = Vec::new();
        for (garbage, message) in &parts {
            stream.extend_from_slice(garbage);
            encode_message(message, &mut stream);
        }
        stream.extend_from_slice(&tail);
        let decoded = decode_stream(&stream)?;
        let mut found = decoded.iter();
        for (_, message) in &parts {
            prop_assert!(
                found.any(|m| m == message),
                "{message:?} not recovered from {:?}: {decoded:?}",
                String::from_utf8_lossy(&stream)
            );
        }
    }

    /// A single flipped bit anywhere in a frame's content is never read as another message
    /// (CRC-8/SMBUS detects every single-bit error).
    #[test]
    fn a_single_bit_error_is_never_read_as_another_message(
        message in board_message(),
        position in any::<prop::sample::Index>(),
        bit in 0u8..8,
    ) {
        let mut encoded = Vec::new();
        encode_message(&message, &mut encoded);
        // Content between `$` and `\n`.
        let end = encoded.len() - 1;
        let content = &mut encoded[1..end];
        let at = position.index(content.len());
        content[at] ^= 1 << bit;
        // The one accepted change: the case of a checksum hex digit (documented: the receiver
        // accepts either case), which leaves the message as it was.
        if let Ok(frame) = decode_frame(content) {
            prop_assert_eq!(
                decode_board_message(&frame).ok(),
                Some(message),
                "{:?}",
                String::from_utf8_lossy(content)
            );
        }
    }

    /// Requests round-trip through the assembler and the request decoder.
    #[test]
    fn requests_round_trip(seq in any::<u8>(), request in request(), garbage in noise(30)) {
        let mut stream = garbage;
        encode_request(seq, &request, &mut stream);
        let mut assembler = LineAssembler::new();
        let mut decoded = None;
        for &byte in &stream {
            if let Some(Ok(line)) = assembler.push(byte)
                && let Ok(frame) = decode_frame(line)
                && let Ok(found) = decode_request(frame.body)
            {
                decoded = Some(found);
            }
        }
        prop_assert_eq!(decoded, Some(request));
    }

    /// Any printable body with a correct checksum and any tag: the message decoders return a
    /// message or an error naming the problem.
    #[test]
    fn checksummed_bodies_of_any_text_never_panic(
        body in "[ -)+-~]{0,60}",
        tag in prop_oneof!["U", "[0-9]{1,3}", "[ -)+-~]{0,4}"],
    ) {
        let covered = format!("{body}*{tag}");
        let crc = harvest_hw::valve_board::protocol::crc8(covered.as_bytes());
        let line = format!("{covered}*{crc:02X}");
        if let Ok(frame) = decode_frame(line.as_bytes()) {
            match decode_board_message(&frame) {
                Ok(_) => {}
                Err(error) => prop_assert!(!error.to_string().is_empty()),
            }
            match decode_request(frame.body) {
                Ok(_) => {}
                Err(error) => prop_assert!(!error.to_string().is_empty()),
            }
        }
    }
}
