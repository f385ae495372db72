//! The valve board's serial line protocol: pure encode/decode functions, no I/O.
//!
//! Every frame is one ASCII line `$<body>*<tag>*<crc>\n` (specification and examples in
//! `hw/VALVE_PROTOCOL.md`):
//! - `body`: space-separated tokens, e.g. `SET 3 1` or `OK VALVES OPEN CLOSED CLOSED CLOSING`;
//! - `tag`: the request's sequence number in decimal (0..=255, echoed by the reply), or `U` on an
//!   unsolicited board line;
//! - `crc`: CRC-8/SMBUS (polynomial 0x07, init 0, no reflection, no final xor) of the bytes
//!   between `$` and the second `*`, as two hex digits.
//!
//! Byte-level framing (finding `$`, the line end, dropping garbage) is in
//! [`super::line_assembler`]; this module turns one assembled line into a [`Frame`] and a frame
//! into a [`Request`] or [`BoardMessage`], and back.

use super::types::{
    BoardFault, PressureReadings, PressureSensor, VALVE_COUNT, ValveId, ValveState, ValveStates,
};

/// Longest frame content accepted, in bytes between `$` and `\n` (the Arduino Uno keeps its
/// line buffer in 2 KiB of RAM). The longest legitimate frame is about 50 bytes.
pub const MAX_FRAME_LEN: usize = 80;

/// Start-of-frame byte.
pub const FRAME_START: u8 = b'$';

/// Separator between body, tag and checksum.
pub const FIELD_SEPARATOR: u8 = b'*';

/// End-of-frame byte (a `\r` before it is ignored).
pub const FRAME_END: u8 = b'\n';

/// Tag of unsolicited board lines.
pub const UNSOLICITED_TAG: &str = "U";

/// CRC-8/SMBUS: polynomial x^8 + x^2 + x + 1 (0x07), initial value 0, no reflection, no final
/// xor. Check value: `crc8(b"123456789") == 0xF4`.
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// What follows the body: which request a line belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Tag {
    /// A request, or the reply to the request with this sequence number.
    Seq(u8),
    /// A line the board sent on its own (a fault).
    Unsolicited,
}

/// A checked frame: its body and tag. The checksum has been verified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Space-separated tokens, printable ASCII.
    pub body: &'a str,
    /// Sequence number or unsolicited marker.
    pub tag: Tag,
}

/// Why a line is not a valid frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The line lacks the `*<tag>*<crc>` trailer.
    #[error("frame has no `*tag*crc` trailer")]
    MissingTrailer,
    /// The checksum field is not two hex digits.
    #[error("frame checksum field is not two hex digits")]
    BadChecksumField,
    /// The tag is neither a decimal 0..=255 nor `U`.
    #[error("frame tag is neither a sequence number 0..=255 nor `U`")]
    BadTag,
    /// The line contains a byte outside printable ASCII.
    #[error("frame contains a byte outside printable ASCII")]
    NotAscii,
    /// The checksum in the frame differs from the one computed over its content.
    #[error("frame checksum {received:02X} does not match computed {computed:02X}")]
    ChecksumMismatch {
        /// Checksum carried by the frame.
        received: u8,
        /// Checksum computed over body and tag.
        computed: u8,
    },
}

/// Decode the content of one line (the bytes between `$` and `\n`, as returned by
/// [`super::line_assembler::LineAssembler::push`]) and verify its checksum.
pub fn decode_frame(line: &[u8]) -> Result<Frame<'_>, FrameError> {
    let text = std::str::from_utf8(line).map_err(|_| FrameError::NotAscii)?;
    if !text.bytes().all(|b| (0x20..=0x7E).contains(&b)) {
        return Err(FrameError::NotAscii);
    }
    let (covered, crc_text) = text.rsplit_once('*').ok_or(FrameError::MissingTrailer)?;
    let (body, tag_text) = covered.rsplit_once('*').ok_or(FrameError::MissingTrailer)?;
    let received = parse_hex2(crc_text).ok_or(FrameError::BadChecksumField)?;
    let tag = parse_tag(tag_text).ok_or(FrameError::BadTag)?;
    let computed = crc8(covered.as_bytes());
    if computed != received {
        return Err(FrameError::ChecksumMismatch { received, computed });
    }
    Ok(Frame { body, tag })
}

fn parse_hex2(text: &str) -> Option<u8> {
    if text.len() != 2 || !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    u8::from_str_radix(text, 16).ok()
}

fn parse_tag(text: &str) -> Option<Tag> {
    if text == UNSOLICITED_TAG {
        return Some(Tag::Unsolicited);
    }
    parse_decimal_u32(text, 3)
        .and_then(|v| u8::try_from(v).ok())
        .map(Tag::Seq)
}

/// Parse an unsigned decimal of 1..=max_digits digits (no sign, no spaces).
fn parse_decimal_u32(text: &str, max_digits: usize) -> Option<u32> {
    if text.is_empty() || text.len() > max_digits || !text.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    text.parse().ok()
}

/// Parse a signed decimal of at most 5 digits (an optional leading `-`).
fn parse_decimal_i32(text: &str) -> Option<i32> {
    let digits = text.strip_prefix('-').unwrap_or(text);
    parse_decimal_u32(digits, 5)
        .and_then(|v| i32::try_from(v).ok())
        .map(|v| if digits.len() < text.len() { -v } else { v })
}

/// Append a whole frame around the body written by `body` to `out`.
fn encode_frame(out: &mut Vec<u8>, tag: Tag, body: impl FnOnce(&mut Vec<u8>)) {
    let start = out.len();
    out.push(FRAME_START);
    body(out);
    out.push(FIELD_SEPARATOR);
    match tag {
        Tag::Seq(seq) => push_u32(out, u32::from(seq)),
        Tag::Unsolicited => out.extend_from_slice(UNSOLICITED_TAG.as_bytes()),
    }
    let crc = crc8(&out[start + 1..]);
    out.push(FIELD_SEPARATOR);
    push_hex2(out, crc);
    out.push(FRAME_END);
}

fn push_u32(out: &mut Vec<u8>, mut value: u32) {
    let mut digits = [0u8; 10];
    let mut first = digits.len();
    loop {
        first -= 1;
        digits[first] = b'0' + (value % 10) as u8;
        value /= 10;
        if value == 0 {
            break;
        }
    }
    out.extend_from_slice(&digits[first..]);
}

fn push_i32(out: &mut Vec<u8>, value: i32) {
    if value < 0 {
        out.push(b'-');
    }
    push_u32(out, value.unsigned_abs());
}

fn push_hex2(out: &mut Vec<u8>, value: u8) {
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    out.push(HEX[usize::from(value >> 4)]);
    out.push(HEX[usize::from(value & 0x0F)]);
}

/// A request from the host to the board. Every request is idempotent (absolute targets, no
/// toggles or counters), so the host may resend it after a lost reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// `PING`: heartbeat.
    Ping,
    /// `SET <valve> <0|1>`: command a valve closed (0) or open (1).
    Set {
        /// Valve 1..=4.
        valve: ValveId,
        /// Target position.
        open: bool,
    },
    /// `VALVES`: read all valve states.
    Valves,
    /// `PRES`: read the three pressure sensors.
    Pressures,
    /// `CLOSEALL`: command every valve closed (emergency).
    CloseAll,
}

impl Request {
    /// The request's verb as sent on the wire.
    pub fn verb(&self) -> &'static str {
        match self {
            Request::Ping => "PING",
            Request::Set { .. } => "SET",
            Request::Valves => "VALVES",
            Request::Pressures => "PRES",
            Request::CloseAll => "CLOSEALL",
        }
    }

    /// True if resending the request after a lost reply cannot change the outcome. True for
    /// every request of this protocol version; a future request that is not (a toggle, a
    /// counter) must return false so the driver does not retry it.
    pub fn is_idempotent(&self) -> bool {
        match self {
            Request::Ping
            | Request::Set { .. }
            | Request::Valves
            | Request::Pressures
            | Request::CloseAll => true,
        }
    }
}

/// Append the frame for `request` with sequence number `seq` to `out`. The valve id is written
/// as given; the driver refuses ids outside 1..=4 before encoding.
pub fn encode_request(seq: u8, request: &Request, out: &mut Vec<u8>) {
    encode_frame(out, Tag::Seq(seq), |out| {
        out.extend_from_slice(request.verb().as_bytes());
        if let Request::Set { valve, open } = request {
            out.push(b' ');
            push_u32(out, u32::from(valve.0));
            out.push(b' ');
            out.push(if *open { b'1' } else { b'0' });
        }
    });
}

/// Why a frame's body is not a valid message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MessageError {
    /// The first token is not a known verb (or status word for replies).
    #[error("unknown verb {verb:?}")]
    UnknownVerb {
        /// The token received.
        verb: String,
    },
    /// The verb takes a different number of arguments.
    #[error("{verb} takes {expected} argument(s), got {got}")]
    WrongArgumentCount {
        /// The verb.
        verb: &'static str,
        /// Arguments it takes.
        expected: usize,
        /// Arguments received.
        got: usize,
    },
    /// More tokens than any message has.
    #[error("{verb} has more than {max} arguments")]
    TooManyArguments {
        /// The verb.
        verb: &'static str,
        /// Most arguments any message takes.
        max: usize,
    },
    /// An argument is not what the verb expects.
    #[error("{verb} argument {field} = {value:?} is invalid (expected {expected})")]
    BadArgument {
        /// The verb.
        verb: &'static str,
        /// Which argument.
        field: &'static str,
        /// The token received.
        value: String,
        /// What was expected.
        expected: &'static str,
    },
    /// A reply carried the unsolicited tag, or a fault line carried a sequence number.
    #[error("{what} line has the wrong tag {tag:?}")]
    WrongTag {
        /// `reply` or `fault`.
        what: &'static str,
        /// The tag received.
        tag: Tag,
    },
}

/// Split a body into its verb and arguments (single spaces, no empty tokens).
fn tokens(body: &str) -> impl Iterator<Item = &str> {
    body.split(' ')
}

fn expect_args(verb: &'static str, args: &[&str], expected: usize) -> Result<(), MessageError> {
    if args.len() == expected {
        Ok(())
    } else {
        Err(MessageError::WrongArgumentCount {
            verb,
            expected,
            got: args.len(),
        })
    }
}

fn bad_argument(
    verb: &'static str,
    field: &'static str,
    value: &str,
    expected: &'static str,
) -> MessageError {
    MessageError::BadArgument {
        verb,
        field,
        value: value.to_owned(),
        expected,
    }
}

fn parse_valve(verb: &'static str, text: &str) -> Result<ValveId, MessageError> {
    parse_decimal_u32(text, 1)
        .and_then(|v| u8::try_from(v).ok())
        .and_then(ValveId::new)
        .ok_or_else(|| bad_argument(verb, "valve", text, "1..=4"))
}

fn parse_flag(verb: &'static str, text: &str) -> Result<bool, MessageError> {
    match text {
        "0" => Ok(false),
        "1" => Ok(true),
        _ => Err(bad_argument(verb, "position", text, "0 or 1")),
    }
}

/// Maximum number of arguments after the verb(s) in any message.
const MAX_ARGS: usize = 4;

/// Collect the arguments after the verb into a fixed array (no allocation).
fn split_args<'a>(
    verb: &'static str,
    rest: impl Iterator<Item = &'a str>,
) -> Result<([&'a str; MAX_ARGS], usize), MessageError> {
    let mut args = [""; MAX_ARGS];
    let mut count = 0;
    for token in rest {
        if count == MAX_ARGS {
            return Err(MessageError::TooManyArguments {
                verb,
                max: MAX_ARGS,
            });
        }
        args[count] = token;
        count += 1;
    }
    Ok((args, count))
}

/// Decode a request body (what the board does with a checked frame from the host).
///
/// A body with a valid verb but a valve outside 1..=4 decodes to
/// `MessageError::BadArgument { field: "valve", .. }`, which the board answers with
/// [`Status::Range`]; any other error is answered with [`Status::Syntax`].
pub fn decode_request(body: &str) -> Result<Request, MessageError> {
    let mut it = tokens(body);
    let verb_text = it.next().unwrap_or("");
    let verb = match verb_text {
        "PING" => Request::Ping.verb(),
        "SET" => "SET",
        "VALVES" => Request::Valves.verb(),
        "PRES" => Request::Pressures.verb(),
        "CLOSEALL" => Request::CloseAll.verb(),
        other => {
            return Err(MessageError::UnknownVerb {
                verb: other.to_owned(),
            });
        }
    };
    let (args, n) = split_args(verb, it)?;
    let args = &args[..n];
    match verb {
        "SET" => {
            expect_args(verb, args, 2)?;
            Ok(Request::Set {
                valve: parse_valve(verb, args[0])?,
                open: parse_flag(verb, args[1])?,
            })
        }
        "PING" => expect_args(verb, args, 0).map(|()| Request::Ping),
        "VALVES" => expect_args(verb, args, 0).map(|()| Request::Valves),
        "PRES" => expect_args(verb, args, 0).map(|()| Request::Pressures),
        _ => expect_args(verb, args, 0).map(|()| Request::CloseAll),
    }
}

/// Status of a refused request, sent as `ERR <code> <name>`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Status {
    /// 1 SYNTAX: unknown verb or malformed arguments (host and firmware disagree on the
    /// protocol).
    Syntax,
    /// 2 RANGE: an argument is outside its range (valve not in 1..=4).
    Range,
    /// 3 FAULT: the board refuses because of a latched fault (the valve is stuck).
    Fault,
}

impl Status {
    /// Numeric code on the wire.
    pub fn code(self) -> u8 {
        match self {
            Status::Syntax => 1,
            Status::Range => 2,
            Status::Fault => 3,
        }
    }

    /// Name on the wire.
    pub fn name(self) -> &'static str {
        match self {
            Status::Syntax => "SYNTAX",
            Status::Range => "RANGE",
            Status::Fault => "FAULT",
        }
    }

    fn from_wire(code: &str, name: &str) -> Option<Status> {
        [Status::Syntax, Status::Range, Status::Fault]
            .into_iter()
            .find(|s| parse_decimal_u32(code, 3) == Some(u32::from(s.code())) && s.name() == name)
    }
}

/// A reply from the board to one request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reply {
    /// `OK PONG <uptime_ms>`.
    Pong {
        /// Board uptime, ms (wrapping `millis()`).
        uptime_ms: u32,
    },
    /// `OK SET <valve> <0|1>`: the command was accepted (the gate starts moving).
    SetAck {
        /// Valve commanded.
        valve: ValveId,
        /// Target position.
        open: bool,
    },
    /// `OK VALVES <s1> <s2> <s3> <s4>`, each `CLOSED`, `OPEN`, `OPENING`, `CLOSING` or `STUCK`.
    Valves(ValveStates),
    /// `OK PRES <arm1> <arm2> <source>`: vacuum in whole mmH2O (signed decimal). Encoding
    /// rounds to the nearest mmH2O, well below the sensors' resolution.
    Pressures(PressureReadings),
    /// `OK CLOSEALL`: every valve commanded closed.
    ClosedAll,
    /// `ERR <code> <name>`: the request was refused.
    Error(Status),
}

impl Reply {
    /// The request verb this reply answers (`None` for an error, which answers any).
    pub fn answers(&self) -> Option<&'static str> {
        match self {
            Reply::Pong { .. } => Some(Request::Ping.verb()),
            Reply::SetAck { .. } => Some("SET"),
            Reply::Valves(_) => Some(Request::Valves.verb()),
            Reply::Pressures(_) => Some(Request::Pressures.verb()),
            Reply::ClosedAll => Some(Request::CloseAll.verb()),
            Reply::Error(_) => None,
        }
    }
}

/// A checked line from the board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoardMessage {
    /// The reply to the request with sequence number `seq`.
    Reply {
        /// Sequence number echoed from the request.
        seq: u8,
        /// The reply.
        reply: Reply,
    },
    /// An unsolicited fault line: `FAULT STUCK <valve>`, `FAULT SENSOR <1..3>`,
    /// `FAULT SUPPLY` or `FAULT RESET`.
    Fault(BoardFault),
}

fn valve_state_token(state: ValveState) -> &'static str {
    match state {
        ValveState::Closed => "CLOSED",
        ValveState::Open => "OPEN",
        ValveState::Opening => "OPENING",
        ValveState::Closing => "CLOSING",
        ValveState::Stuck => "STUCK",
    }
}

fn parse_valve_state(text: &str) -> Result<ValveState, MessageError> {
    match text {
        "CLOSED" => Ok(ValveState::Closed),
        "OPEN" => Ok(ValveState::Open),
        "OPENING" => Ok(ValveState::Opening),
        "CLOSING" => Ok(ValveState::Closing),
        "STUCK" => Ok(ValveState::Stuck),
        _ => Err(bad_argument(
            "VALVES",
            "state",
            text,
            "CLOSED, OPEN, OPENING, CLOSING or STUCK",
        )),
    }
}

/// Pressure as whole mmH2O on the wire, clamped to what 5 digits carry.
fn pressure_to_wire(vacuum_mmh2o: f32) -> i32 {
    if vacuum_mmh2o.is_finite() {
        vacuum_mmh2o.round().clamp(-99_999.0, 99_999.0) as i32
    } else {
        0
    }
}

/// Append the frame for `reply` to the request numbered `seq` to `out`.
pub fn encode_reply(seq: u8, reply: &Reply, out: &mut Vec<u8>) {
    encode_frame(out, Tag::Seq(seq), |out| match reply {
        Reply::Error(status) => {
            out.extend_from_slice(b"ERR ");
            push_u32(out, u32::from(status.code()));
            out.push(b' ');
            out.extend_from_slice(status.name().as_bytes());
        }
        Reply::Pong { uptime_ms } => {
            out.extend_from_slice(b"OK PONG ");
            push_u32(out, *uptime_ms);
        }
        Reply::SetAck { valve, open } => {
            out.extend_from_slice(b"OK SET ");
            push_u32(out, u32::from(valve.0));
            out.push(b' ');
            out.push(if *open { b'1' } else { b'0' });
        }
        Reply::Valves(states) => {
            out.extend_from_slice(b"OK VALVES");
            for state in states.0 {
                out.push(b' ');
                out.extend_from_slice(valve_state_token(state).as_bytes());
            }
        }
        Reply::Pressures(p) => {
            out.extend_from_slice(b"OK PRES");
            for v in p.to_array() {
                out.push(b' ');
                push_i32(out, pressure_to_wire(v));
            }
        }
        Reply::ClosedAll => out.extend_from_slice(b"OK CLOSEALL"),
    });
}

/// Append the unsolicited frame reporting `fault` to `out`.
pub fn encode_fault(fault: &BoardFault, out: &mut Vec<u8>) {
    encode_frame(out, Tag::Unsolicited, |out| {
        out.extend_from_slice(b"FAULT ");
        match fault {
            BoardFault::ValveStuck(v) => {
                out.extend_from_slice(b"STUCK ");
                push_u32(out, u32::from(v.0));
            }
            BoardFault::SensorFault(s) => {
                out.extend_from_slice(b"SENSOR ");
                push_u32(out, u32::from(s.number()));
            }
            BoardFault::SupplyLow => out.extend_from_slice(b"SUPPLY"),
            BoardFault::BoardReset => out.extend_from_slice(b"RESET"),
        }
    });
}

/// Decode a checked frame from the board into a reply or a fault.
pub fn decode_board_message(frame: &Frame<'_>) -> Result<BoardMessage, MessageError> {
    let mut it = tokens(frame.body);
    let first = it.next().unwrap_or("");
    match (first, frame.tag) {
        ("FAULT", Tag::Unsolicited) => decode_fault(it).map(BoardMessage::Fault),
        ("FAULT", tag) => Err(MessageError::WrongTag { what: "fault", tag }),
        ("OK" | "ERR", Tag::Unsolicited) => Err(MessageError::WrongTag {
            what: "reply",
            tag: Tag::Unsolicited,
        }),
        ("OK", Tag::Seq(seq)) => decode_ok(it).map(|reply| BoardMessage::Reply { seq, reply }),
        ("ERR", Tag::Seq(seq)) => {
            let (args, n) = split_args("ERR", it)?;
            expect_args("ERR", &args[..n], 2)?;
            let status = Status::from_wire(args[0], args[1]).ok_or_else(|| {
                bad_argument("ERR", "status", args[0], "1 SYNTAX, 2 RANGE or 3 FAULT")
            })?;
            Ok(BoardMessage::Reply {
                seq,
                reply: Reply::Error(status),
            })
        }
        (other, _) => Err(MessageError::UnknownVerb {
            verb: other.to_owned(),
        }),
    }
}

fn decode_fault<'a>(mut it: impl Iterator<Item = &'a str>) -> Result<BoardFault, MessageError> {
    let kind = it.next().unwrap_or("");
    let (args, n) = split_args("FAULT", it)?;
    let args = &args[..n];
    match kind {
        "STUCK" => {
            expect_args("FAULT", args, 1)?;
            parse_valve("FAULT", args[0]).map(BoardFault::ValveStuck)
        }
        "SENSOR" => {
            expect_args("FAULT", args, 1)?;
            parse_decimal_u32(args[0], 1)
                .and_then(|v| u8::try_from(v).ok())
                .and_then(PressureSensor::from_number)
                .map(BoardFault::SensorFault)
                .ok_or_else(|| bad_argument("FAULT", "sensor", args[0], "1..=3"))
        }
        "SUPPLY" => expect_args("FAULT", args, 0).map(|()| BoardFault::SupplyLow),
        "RESET" => expect_args("FAULT", args, 0).map(|()| BoardFault::BoardReset),
        other => Err(bad_argument(
            "FAULT",
            "kind",
            other,
            "STUCK, SENSOR, SUPPLY or RESET",
        )),
    }
}

fn decode_ok<'a>(mut it: impl Iterator<Item = &'a str>) -> Result<Reply, MessageError> {
    let verb_text = it.next().unwrap_or("");
    let verb: &'static str = match verb_text {
        "PONG" => "PONG",
        "SET" => "SET",
        "VALVES" => "VALVES",
        "PRES" => "PRES",
        "CLOSEALL" => "CLOSEALL",
        other => {
            return Err(MessageError::UnknownVerb {
                verb: format!("OK {other}"),
            });
        }
    };
    let (args, n) = split_args(verb, it)?;
    let args = &args[..n];
    match verb {
        "PONG" => {
            expect_args(verb, args, 1)?;
            parse_decimal_u32(args[0], 10)
                .map(|uptime_ms| Reply::Pong { uptime_ms })
                .ok_or_else(|| bad_argument(verb, "uptime_ms", args[0], "0..=4294967295"))
        }
        "SET" => {
            expect_args(verb, args, 2)?;
            Ok(Reply::SetAck {
                valve: parse_valve(verb, args[0])?,
                open: parse_flag(verb, args[1])?,
            })
        }
        "VALVES" => {
            expect_args(verb, args, VALVE_COUNT)?;
            let mut states = [ValveState::Closed; VALVE_COUNT];
            for (state, text) in states.iter_mut().zip(args) {
                *state = parse_valve_state(text)?;
            }
            Ok(Reply::Valves(ValveStates(states)))
        }
        "PRES" => {
            expect_args(verb, args, 3)?;
            let mut vacuum_mmh2o = [0.0f32; 3];
            for (v, text) in vacuum_mmh2o.iter_mut().zip(args) {
                *v = parse_decimal_i32(text)
                    .ok_or_else(|| bad_argument(verb, "vacuum_mmh2o", text, "signed integer"))?
                    as f32;
            }
            Ok(Reply::Pressures(PressureReadings::from_array(vacuum_mmh2o)))
        }
        _ => expect_args(verb, args, 0).map(|()| Reply::ClosedAll),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The line content between `$` and `\n` of an encoded frame.
    fn content(encoded: &[u8]) -> &[u8] {
        assert_eq!(encoded.first(), Some(&b'$'));
        assert_eq!(encoded.last(), Some(&b'\n'));
        &encoded[1..encoded.len() - 1]
    }

    #[test]
    fn crc8_smbus_check_value() {
        assert_eq!(crc8(b"123456789"), 0xF4);
        assert_eq!(crc8(b""), 0x00);
    }

    #[test]
    fn known_request_encoding() {
        let mut out = Vec::new();
        encode_request(
            17,
            &Request::Set {
                valve: ValveId(3),
                open: true,
            },
            &mut out,
        );
        let crc = crc8(b"SET 3 1*17");
        assert_eq!(out, format!("$SET 3 1*17*{crc:02X}\n").into_bytes());
    }

    #[test]
    fn documented_example_frames() {
        // The example exchange in hw/VALVE_PROTOCOL.md.
        let mut out = Vec::new();
        encode_request(
            17,
            &Request::Set {
                valve: ValveId(3),
                open: true,
            },
            &mut out,
        );
        encode_reply(
            17,
            &Reply::SetAck {
                valve: ValveId(3),
                open: true,
            },
            &mut out,
        );
        encode_fault(&BoardFault::ValveStuck(ValveId(3)), &mut out);
        assert_eq!(
            String::from_utf8(out).expect("ascii"),
            "$SET 3 1*17*42\n$OK SET 3 1*17*2D\n$FAULT STUCK 3*U*5A\n"
        );
    }

    #[test]
    fn requests_round_trip() {
        let mut requests = vec![
            Request::Ping,
            Request::Valves,
            Request::Pressures,
            Request::CloseAll,
        ];
        for valve in ValveId::ALL {
            for open in [false, true] {
                requests.push(Request::Set { valve, open });
            }
        }
        for (i, request) in requests.iter().enumerate() {
            let seq = (i * 37 % 256) as u8;
            let mut out = Vec::new();
            encode_request(seq, request, &mut out);
            let frame = decode_frame(content(&out)).expect("valid frame");
            assert_eq!(frame.tag, Tag::Seq(seq));
            assert_eq!(decode_request(frame.body), Ok(*request));
            assert!(request.is_idempotent());
        }
    }

    #[test]
    fn replies_and_faults_round_trip() {
        let replies = [
            Reply::Pong {
                uptime_ms: u32::MAX,
            },
            Reply::Pong { uptime_ms: 0 },
            Reply::SetAck {
                valve: ValveId(4),
                open: false,
            },
            Reply::Valves(ValveStates([
                ValveState::Closed,
                ValveState::Open,
                ValveState::Opening,
                ValveState::Stuck,
            ])),
            Reply::Valves(ValveStates([ValveState::Closing; 4])),
            Reply::Pressures(PressureReadings::from_array([1834.0, -12.0, 2499.0])),
            Reply::ClosedAll,
            Reply::Error(Status::Syntax),
            Reply::Error(Status::Range),
            Reply::Error(Status::Fault),
        ];
        for (seq, reply) in replies.iter().enumerate() {
            let mut out = Vec::new();
            encode_reply(seq as u8, reply, &mut out);
            assert!(out.len() - 2 <= MAX_FRAME_LEN, "{out:?} too long");
            let frame = decode_frame(content(&out)).expect("valid frame");
            assert_eq!(
                decode_board_message(&frame),
                Ok(BoardMessage::Reply {
                    seq: seq as u8,
                    reply: *reply
                })
            );
        }
        let faults = [
            BoardFault::ValveStuck(ValveId(2)),
            BoardFault::SensorFault(PressureSensor::Source),
            BoardFault::SupplyLow,
            BoardFault::BoardReset,
        ];
        for fault in faults {
            let mut out = Vec::new();
            encode_fault(&fault, &mut out);
            let frame = decode_frame(content(&out)).expect("valid frame");
            assert_eq!(frame.tag, Tag::Unsolicited);
            assert_eq!(decode_board_message(&frame), Ok(BoardMessage::Fault(fault)));
        }
    }

    #[test]
    fn pressure_encoding_rounds_to_whole_mmh2o() {
        let mut out = Vec::new();
        let p = PressureReadings::from_array([1200.4, 0.6, -3.5]);
        encode_reply(1, &Reply::Pressures(p), &mut out);
        let frame = decode_frame(content(&out)).expect("valid frame");
        assert!(
            frame.body.starts_with("OK PRES 1200 1 -4"),
            "{}",
            frame.body
        );
    }

    #[test]
    fn corrupt_checksum_is_rejected() {
        let mut out = Vec::new();
        encode_request(5, &Request::Ping, &mut out);
        let line = content(&out).to_vec();
        // Flip one bit of the body.
        let mut flipped = line.clone();
        flipped[0] ^= 0x01;
        assert!(matches!(
            decode_frame(&flipped),
            Err(FrameError::ChecksumMismatch { .. })
        ));
        // Replace the checksum itself.
        let mut wrong = line.clone();
        let n = wrong.len();
        wrong[n - 2..].copy_from_slice(if &line[n - 2..] == b"00" {
            b"01"
        } else {
            b"00"
        });
        assert!(matches!(
            decode_frame(&wrong),
            Err(FrameError::ChecksumMismatch { .. })
        ));
        // Lower-case hex is accepted.
        let lower = String::from_utf8(line.clone())
            .expect("ascii")
            .to_ascii_lowercase();
        let (body_tag, crc) = lower.rsplit_once('*').expect("trailer");
        let relowered = format!("{}*{crc}", body_tag.to_ascii_uppercase());
        assert!(decode_frame(relowered.as_bytes()).is_ok());
    }

    #[test]
    fn truncated_and_malformed_frames_are_rejected() {
        let mut out = Vec::new();
        encode_request(200, &Request::Valves, &mut out);
        let line = content(&out);
        // Every strict prefix is invalid.
        for cut in 0..line.len() {
            assert!(decode_frame(&line[..cut]).is_err(), "prefix {cut} accepted");
        }
        assert_eq!(decode_frame(b"PING"), Err(FrameError::MissingTrailer));
        assert_eq!(decode_frame(b"PING*1"), Err(FrameError::MissingTrailer));
        assert_eq!(
            decode_frame(b"PING*1*G0"),
            Err(FrameError::BadChecksumField)
        );
        assert_eq!(decode_frame(b"PING*1*0"), Err(FrameError::BadChecksumField));
        let bad_tag = format!("PING*256*{:02X}", crc8(b"PING*256"));
        assert_eq!(decode_frame(bad_tag.as_bytes()), Err(FrameError::BadTag));
        let plus_tag = format!("PING*+1*{:02X}", crc8(b"PING*+1"));
        assert_eq!(decode_frame(plus_tag.as_bytes()), Err(FrameError::BadTag));
        assert_eq!(decode_frame(b"PI\x01NG*1*00"), Err(FrameError::NotAscii));
    }

    #[test]
    fn bad_request_bodies_are_rejected() {
        assert!(matches!(
            decode_request("OPEN 3"),
            Err(MessageError::UnknownVerb { .. })
        ));
        assert!(matches!(
            decode_request("SET 5 1"),
            Err(MessageError::BadArgument { field: "valve", .. })
        ));
        assert!(matches!(
            decode_request("SET 0 1"),
            Err(MessageError::BadArgument { field: "valve", .. })
        ));
        assert!(matches!(
            decode_request("SET 3 2"),
            Err(MessageError::BadArgument {
                field: "position",
                ..
            })
        ));
        assert!(matches!(
            decode_request("SET 3"),
            Err(MessageError::WrongArgumentCount { got: 1, .. })
        ));
        assert!(matches!(
            decode_request("PING 1"),
            Err(MessageError::WrongArgumentCount { .. })
        ));
        assert!(matches!(
            decode_request("SET  3 1"),
            Err(MessageError::WrongArgumentCount { got: 3, .. })
        ));
        assert!(decode_request("SET 1 1 1 1 1 1").is_err());
        assert!(decode_request("").is_err());
    }

    #[test]
    fn bad_board_bodies_are_rejected() {
        let check = |body: &str, tag: Tag| decode_board_message(&Frame { body, tag });
        assert!(check("OK VALVES OPEN OPEN OPEN", Tag::Seq(1)).is_err());
        assert!(check("OK VALVES OPEN OPEN OPEN HALF", Tag::Seq(1)).is_err());
        assert!(check("OK PRES 1 2", Tag::Seq(1)).is_err());
        assert!(check("OK PRES 1 2 x", Tag::Seq(1)).is_err());
        assert!(check("OK PONG -1", Tag::Seq(1)).is_err());
        assert!(check("ERR 2 SYNTAX", Tag::Seq(1)).is_err());
        assert!(check("ERR 9 WHAT", Tag::Seq(1)).is_err());
        assert!(check("OK PONG 5", Tag::Unsolicited).is_err());
        assert!(check("FAULT RESET", Tag::Seq(3)).is_err());
        assert!(check("FAULT STUCK 7", Tag::Unsolicited).is_err());
        assert!(check("HELLO", Tag::Seq(3)).is_err());
        assert_eq!(
            check("OK PRES -2500 0 99999", Tag::Seq(9)),
            Ok(BoardMessage::Reply {
                seq: 9,
                reply: Reply::Pressures(PressureReadings::from_array([-2500.0, 0.0, 99999.0]))
            })
        );
    }
}
