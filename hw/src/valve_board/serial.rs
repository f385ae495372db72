//! Driver for the real valve board: an Arduino on a serial line speaking the protocol of
//! `hw/VALVE_PROTOCOL.md`.
//!
//! Each request is one bounded exchange: write the frame, read until the reply with the same
//! sequence number arrives or the per-request timeout expires. Idempotent requests (all of
//! them in this protocol version) are resent with a fresh sequence number up to
//! `max_attempts` times; late replies to earlier attempts are recognised by their sequence
//! number and dropped. Noise, cut frames and bad checksums are skipped (the framing
//! resynchronises on the next `$`); unsolicited fault lines seen while waiting are queued for
//! [`ValveBoard::take_faults`].

use super::line_assembler::{AssemblyError, LineAssembler};
use super::protocol::{
    BoardMessage, FrameError, MessageError, Reply, Request, Status, decode_board_message,
    decode_frame, encode_request,
};
use super::{BoardFault, Heartbeat, PressureReadings, ValveBoard, ValveId, ValveStates};
use crate::error_kind::{DeviceError, ErrorKind};
use serialport::SerialPort;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};
use tracing::{debug, trace, warn};

/// Serial settings and timing of the valve board driver.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialBoardConfig {
    /// Serial device, e.g. `/dev/ttyACM0` for an Arduino Uno on USB.
    pub path: String,
    /// Line speed, bits per second.
    #[serde(default = "SerialBoardConfig::default_baud_rate")]
    pub baud_rate: u32,
    /// How long one attempt waits for its reply, ms. A reply of ~50 bytes takes ~4 ms on the
    /// wire at 115200 baud; the rest is USB latency and the firmware's loop period.
    #[serde(default = "SerialBoardConfig::default_request_timeout_ms")]
    pub request_timeout_ms: u64,
    /// Attempts per idempotent request (1 = no retry).
    #[serde(default = "SerialBoardConfig::default_max_attempts")]
    pub max_attempts: u32,
    /// How long [`SerialValveBoard::open`] keeps pinging a board that does not answer yet,
    /// ms. Opening the port of an Arduino Uno resets it and its bootloader runs for ~1.6 s
    /// before the firmware answers.
    #[serde(default = "SerialBoardConfig::default_boot_timeout_ms")]
    pub boot_timeout_ms: u64,
}

impl SerialBoardConfig {
    fn default_baud_rate() -> u32 {
        115_200
    }

    fn default_request_timeout_ms() -> u64 {
        100
    }

    fn default_max_attempts() -> u32 {
        3
    }

    fn default_boot_timeout_ms() -> u64 {
        3_000
    }

    /// Defaults for the board on `path`.
    pub fn new(path: impl Into<String>) -> SerialBoardConfig {
        SerialBoardConfig {
            path: path.into(),
            baud_rate: Self::default_baud_rate(),
            request_timeout_ms: Self::default_request_timeout_ms(),
            max_attempts: Self::default_max_attempts(),
            boot_timeout_ms: Self::default_boot_timeout_ms(),
        }
    }

    fn request_timeout(&self) -> Duration {
        Duration::from_millis(self.request_timeout_ms.max(1))
    }
}

/// A malformed or unreadable line seen while waiting for a reply.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProtocolIssue {
    /// Bytes that started a frame did not make a line.
    #[error("framing: {0}")]
    Framing(#[from] AssemblyError),
    /// A line failed its checksum or frame syntax.
    #[error("frame: {0}")]
    Frame(#[from] FrameError),
    /// A checked line had a body the driver does not understand.
    #[error("message: {0}")]
    Message(#[from] MessageError),
}

/// Errors of valve board requests over a serial line.
#[derive(Debug, thiserror::Error)]
pub enum SerialBoardError {
    /// The port went away (cable unplugged, USB reset, other end closed) while doing
    /// `request`. The driver stays disconnected: drop it and open a new one.
    #[error("valve board on {port} disconnected during {request}: {source}")]
    Disconnected {
        /// Port path.
        port: String,
        /// Request verb.
        request: &'static str,
        /// The I/O error that showed it.
        #[source]
        source: io::Error,
    },
    /// An earlier request found the port disconnected; nothing was sent.
    #[error("valve board on {port} was disconnected earlier; {request} not sent, reopen the port")]
    StillDisconnected {
        /// Port path.
        port: String,
        /// Request verb.
        request: &'static str,
    },
    /// No reply (valid or not) arrived for any attempt.
    #[error(
        "valve board on {port} did not answer {request}: {attempts} attempt(s) of {timeout_ms} ms each"
    )]
    Timeout {
        /// Port path.
        port: String,
        /// Request verb.
        request: &'static str,
        /// Attempts made.
        attempts: u32,
        /// Timeout of each attempt, ms.
        timeout_ms: u64,
    },
    /// Only unreadable data came back for every attempt.
    #[error(
        "valve board on {port} sent no valid reply to {request} in {attempts} attempt(s); last problem: {issue}"
    )]
    Protocol {
        /// Port path.
        port: String,
        /// Request verb.
        request: &'static str,
        /// Attempts made.
        attempts: u32,
        /// The last malformed line seen.
        #[source]
        issue: Box<ProtocolIssue>,
    },
    /// The reply carried our sequence number but answers a different request or echoes a
    /// different valve command (firmware bug or protocol mismatch).
    #[error("valve board on {port} answered {request} with {reply:?}")]
    UnexpectedReply {
        /// Port path.
        port: String,
        /// Request verb.
        request: &'static str,
        /// What came back.
        reply: Reply,
    },
    /// The board refused the request with `ERR <code> <name>`.
    #[error("valve board on {port} refused {request}: ERR {} {}", status.code(), status.name())]
    Refused {
        /// Port path.
        port: String,
        /// Request verb.
        request: &'static str,
        /// The status the board sent.
        status: Status,
    },
    /// The valve id is not on the board; nothing was sent.
    #[error("valve {valve} is not on the board (valves are 1..=4); request not sent")]
    InvalidValve {
        /// The id asked for.
        valve: u8,
    },
}

impl DeviceError for SerialBoardError {
    fn kind(&self) -> ErrorKind {
        match self {
            SerialBoardError::Disconnected { .. } | SerialBoardError::StillDisconnected { .. } => {
                ErrorKind::Disconnected
            }
            SerialBoardError::Timeout { .. } => ErrorKind::Timeout,
            SerialBoardError::Protocol { .. } | SerialBoardError::UnexpectedReply { .. } => {
                ErrorKind::Protocol
            }
            SerialBoardError::Refused { status, .. } => match status {
                Status::Syntax => ErrorKind::Protocol,
                Status::Range => ErrorKind::InvalidRequest,
                Status::Fault => ErrorKind::Fault,
            },
            SerialBoardError::InvalidValve { .. } => ErrorKind::InvalidRequest,
        }
    }
}

/// Errors of [`SerialValveBoard::open`].
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The serial port could not be opened or configured.
    #[error("cannot open valve board port {path} at {baud_rate} baud: {source}")]
    Port {
        /// Port path.
        path: String,
        /// Requested line speed.
        baud_rate: u32,
        /// What serialport reported.
        #[source]
        source: serialport::Error,
    },
    /// The port opened but the board never answered a ping within the boot timeout.
    #[error("valve board on {path} did not answer within {boot_timeout_ms} ms of opening")]
    NoAnswer {
        /// Port path.
        path: String,
        /// Boot timeout, ms.
        boot_timeout_ms: u64,
        /// The last ping's error.
        #[source]
        source: Box<SerialBoardError>,
    },
}

impl DeviceError for OpenError {
    fn kind(&self) -> ErrorKind {
        match self {
            OpenError::Port { .. } => ErrorKind::Disconnected,
            OpenError::NoAnswer { source, .. } => source.kind(),
        }
    }
}

/// Counters of one driver's traffic, for health reporting.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SerialBoardStats {
    /// Requests started (each counted once however many attempts it took).
    pub requests: u64,
    /// Attempts beyond the first.
    pub retries: u64,
    /// Attempts that ended without a valid reply.
    pub failed_attempts: u64,
    /// Valid replies carrying another request's sequence number (late answers to earlier
    /// attempts), dropped.
    pub stale_replies: u64,
    /// Cut, overlong, badly checksummed or unparseable lines, dropped.
    pub bad_lines: u64,
    /// Noise bytes dropped between frames.
    pub noise_bytes: u64,
    /// Unsolicited fault lines received.
    pub faults: u64,
}

/// Why one attempt ended without the awaited reply.
enum AttemptEnd {
    /// Nothing usable arrived before the deadline; `issue` is the last malformed line if any.
    NoReply { issue: Option<ProtocolIssue> },
    /// The port failed.
    Disconnected(io::Error),
}

/// The real valve board on a serial port.
pub struct SerialValveBoard {
    port: Box<dyn SerialPort>,
    port_name: String,
    request_timeout: Duration,
    max_attempts: u32,
    next_seq: u8,
    assembler: LineAssembler,
    tx: Vec<u8>,
    faults: Vec<BoardFault>,
    stats: SerialBoardStats,
    disconnected: bool,
}

impl std::fmt::Debug for SerialValveBoard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialValveBoard")
            .field("port", &self.port_name)
            .field("request_timeout", &self.request_timeout)
            .field("max_attempts", &self.max_attempts)
            .field("stats", &self.stats)
            .field("disconnected", &self.disconnected)
            .finish_non_exhaustive()
    }
}

/// True for I/O errors that are a per-read timeout rather than a failure.
fn is_timeout(error: &io::Error) -> bool {
    matches!(
        error.kind(),
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
    )
}

impl SerialValveBoard {
    /// Open the port in `config`, then ping until the board answers or
    /// `config.boot_timeout_ms` passes.
    pub fn open(config: &SerialBoardConfig) -> Result<SerialValveBoard, OpenError> {
        let port = serialport::new(&config.path, config.baud_rate)
            .timeout(config.request_timeout())
            .open()
            .map_err(|source| OpenError::Port {
                path: config.path.clone(),
                baud_rate: config.baud_rate,
                source,
            })?;
        if let Err(error) = port.clear(serialport::ClearBuffer::All) {
            debug!(port = %config.path, %error, "could not clear serial buffers after open");
        }
        let mut board = SerialValveBoard::with_port(port, config);
        board
            .wait_for_board(Duration::from_millis(config.boot_timeout_ms))
            .map_err(|source| OpenError::NoAnswer {
                path: config.path.clone(),
                boot_timeout_ms: config.boot_timeout_ms,
                source: Box::new(source),
            })?;
        Ok(board)
    }

    /// Use an already open port (no handshake). `config.path` only names the port in errors
    /// and logs; `baud_rate` and `boot_timeout_ms` are not used.
    pub fn with_port(port: Box<dyn SerialPort>, config: &SerialBoardConfig) -> SerialValveBoard {
        SerialValveBoard {
            port,
            port_name: config.path.clone(),
            request_timeout: config.request_timeout(),
            max_attempts: config.max_attempts.max(1),
            next_seq: 0,
            assembler: LineAssembler::new(),
            tx: Vec::with_capacity(64),
            faults: Vec::new(),
            stats: SerialBoardStats::default(),
            disconnected: false,
        }
    }

    /// Ping until the board answers or `boot_timeout` passes (after opening the port, or after
    /// a [`BoardFault::BoardReset`]). Stops at once if the port is disconnected.
    pub fn wait_for_board(
        &mut self,
        boot_timeout: Duration,
    ) -> Result<Heartbeat, SerialBoardError> {
        let deadline = Instant::now() + boot_timeout;
        loop {
            match self.ping() {
                Ok(heartbeat) => return Ok(heartbeat),
                Err(error) if error.kind() == ErrorKind::Disconnected => return Err(error),
                Err(error) if Instant::now() >= deadline => return Err(error),
                Err(error) => debug!(port = %self.port_name, %error, "board not answering yet"),
            }
        }
    }

    /// Traffic counters since the driver was created.
    pub fn stats(&self) -> SerialBoardStats {
        SerialBoardStats {
            noise_bytes: self.assembler.discarded_bytes(),
            ..self.stats
        }
    }

    /// The port path given at creation.
    pub fn port_name(&self) -> &str {
        &self.port_name
    }

    fn take_seq(&mut self) -> u8 {
        let seq = self.next_seq;
        self.next_seq = self.next_seq.wrapping_add(1);
        seq
    }

    fn disconnected_error(&mut self, request: &Request, source: io::Error) -> SerialBoardError {
        self.disconnected = true;
        warn!(port = %self.port_name, request = request.verb(), error = %source, "valve board disconnected");
        SerialBoardError::Disconnected {
            port: self.port_name.clone(),
            request: request.verb(),
            source,
        }
    }

    /// Send `request` and return the board's reply, retrying idempotent requests.
    fn transact(&mut self, request: Request) -> Result<Reply, SerialBoardError> {
        if self.disconnected {
            return Err(SerialBoardError::StillDisconnected {
                port: self.port_name.clone(),
                request: request.verb(),
            });
        }
        self.stats.requests += 1;
        let attempts = if request.is_idempotent() {
            self.max_attempts
        } else {
            1
        };
        let mut last_issue = None;
        for attempt in 1..=attempts {
            if attempt > 1 {
                self.stats.retries += 1;
                debug!(port = %self.port_name, request = request.verb(), attempt, "retrying valve board request");
            }
            let seq = self.take_seq();
            self.tx.clear();
            encode_request(seq, &request, &mut self.tx);
            trace!(port = %self.port_name, frame = %String::from_utf8_lossy(&self.tx).trim_end(), "valve board request");
            let end = match self.write_request() {
                Ok(()) => self.await_reply(seq),
                Err(error) if is_timeout(&error) => Err(AttemptEnd::NoReply { issue: None }),
                Err(error) => Err(AttemptEnd::Disconnected(error)),
            };
            match end {
                Ok(Reply::Error(status)) => {
                    return Err(SerialBoardError::Refused {
                        port: self.port_name.clone(),
                        request: request.verb(),
                        status,
                    });
                }
                Ok(reply) => return self.check_reply(&request, reply),
                Err(AttemptEnd::Disconnected(error)) => {
                    return Err(self.disconnected_error(&request, error));
                }
                Err(AttemptEnd::NoReply { issue }) => {
                    self.stats.failed_attempts += 1;
                    if issue.is_some() {
                        last_issue = issue;
                    }
                }
            }
        }
        Err(match last_issue {
            Some(issue) => SerialBoardError::Protocol {
                port: self.port_name.clone(),
                request: request.verb(),
                attempts,
                issue: Box::new(issue),
            },
            None => SerialBoardError::Timeout {
                port: self.port_name.clone(),
                request: request.verb(),
                attempts,
                timeout_ms: self.request_timeout.as_millis() as u64,
            },
        })
    }

    fn check_reply(&self, request: &Request, reply: Reply) -> Result<Reply, SerialBoardError> {
        let matches = match (request, &reply) {
            (
                Request::Set { valve, open },
                Reply::SetAck {
                    valve: acked,
                    open: acked_open,
                },
            ) => valve == acked && open == acked_open,
            _ => reply.answers() == Some(request.verb()),
        };
        if matches {
            Ok(reply)
        } else {
            Err(SerialBoardError::UnexpectedReply {
                port: self.port_name.clone(),
                request: request.verb(),
                reply,
            })
        }
    }

    fn write_request(&mut self) -> io::Result<()> {
        self.port
            .set_timeout(self.request_timeout)
            .map_err(io::Error::from)?;
        self.port.write_all(&self.tx)
    }

    /// Read until the reply numbered `seq` arrives or the attempt's deadline passes.
    fn await_reply(&mut self, seq: u8) -> Result<Reply, AttemptEnd> {
        let deadline = Instant::now() + self.request_timeout;
        let mut rx = [0u8; 128];
        let mut issue: Option<ProtocolIssue> = None;
        loop {
            let now = Instant::now();
            if now >= deadline {
                return Err(AttemptEnd::NoReply { issue });
            }
            if let Err(error) = self.port.set_timeout(deadline - now) {
                return Err(AttemptEnd::Disconnected(io::Error::from(error)));
            }
            let n = match self.port.read(&mut rx) {
                Ok(0) => {
                    return Err(AttemptEnd::Disconnected(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "serial port returned end of file",
                    )));
                }
                Ok(n) => n,
                Err(error) if is_timeout(&error) => continue,
                Err(error) => return Err(AttemptEnd::Disconnected(error)),
            };
            // Feed the whole chunk even after our reply, so a fault line right behind it is
            // not lost.
            let mut found = None;
            for &byte in &rx[..n] {
                let Some(event) = self.assembler.push(byte) else {
                    continue;
                };
                let message = event
                    .map_err(ProtocolIssue::from)
                    .and_then(|line| decode_frame(line).map_err(ProtocolIssue::from))
                    .and_then(|frame| decode_board_message(&frame).map_err(ProtocolIssue::from));
                match message {
                    Err(bad) => {
                        self.stats.bad_lines += 1;
                        debug!(port = %self.port_name, problem = %bad, "dropped bad line from valve board");
                        issue = Some(bad);
                    }
                    Ok(BoardMessage::Fault(fault)) => {
                        self.stats.faults += 1;
                        warn!(port = %self.port_name, %fault, "valve board reported a fault");
                        self.faults.push(fault);
                    }
                    Ok(BoardMessage::Reply { seq: got, reply }) if got == seq => {
                        trace!(port = %self.port_name, seq, ?reply, "valve board reply");
                        if found.is_none() {
                            found = Some(reply);
                        }
                    }
                    Ok(BoardMessage::Reply { seq: got, .. }) => {
                        self.stats.stale_replies += 1;
                        debug!(port = %self.port_name, expected = seq, got, "dropped stale valve board reply");
                    }
                }
            }
            if let Some(reply) = found {
                return Ok(reply);
            }
        }
    }

    fn check_valve(valve: ValveId) -> Result<(), SerialBoardError> {
        if valve.is_valid() {
            Ok(())
        } else {
            Err(SerialBoardError::InvalidValve { valve: valve.0 })
        }
    }
}

impl ValveBoard for SerialValveBoard {
    type Error = SerialBoardError;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        Self::check_valve(valve)?;
        self.transact(Request::Set { valve, open }).map(|_| ())
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        match self.transact(Request::Valves)? {
            Reply::Valves(states) => Ok(states),
            reply => Err(SerialBoardError::UnexpectedReply {
                port: self.port_name.clone(),
                request: Request::Valves.verb(),
                reply,
            }),
        }
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        match self.transact(Request::Pressures)? {
            Reply::Pressures(p) => Ok(p),
            reply => Err(SerialBoardError::UnexpectedReply {
                port: self.port_name.clone(),
                request: Request::Pressures.verb(),
                reply,
            }),
        }
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        self.transact(Request::CloseAll).map(|_| ())
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        match self.transact(Request::Ping)? {
            Reply::Pong { uptime_ms } => Ok(Heartbeat {
                board_uptime_ms: uptime_ms,
            }),
            reply => Err(SerialBoardError::UnexpectedReply {
                port: self.port_name.clone(),
                request: Request::Ping.verb(),
                reply,
            }),
        }
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        std::mem::take(&mut self.faults)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(status: Status) -> SerialBoardError {
        SerialBoardError::Refused {
            port: "/dev/null".to_owned(),
            request: "SET",
            status,
        }
    }

    #[test]
    fn error_kinds() {
        assert_eq!(refused(Status::Range).kind(), ErrorKind::InvalidRequest);
        assert_eq!(refused(Status::Fault).kind(), ErrorKind::Fault);
        assert_eq!(refused(Status::Syntax).kind(), ErrorKind::Protocol);
        assert_eq!(
            SerialBoardError::InvalidValve { valve: 9 }.kind(),
            ErrorKind::InvalidRequest
        );
        let timeout = SerialBoardError::Timeout {
            port: "p".to_owned(),
            request: "PING",
            attempts: 3,
            timeout_ms: 100,
        };
        assert_eq!(timeout.kind(), ErrorKind::Timeout);
        assert!(timeout.to_string().contains("3 attempt(s) of 100 ms"));
        let gone = SerialBoardError::Disconnected {
            port: "p".to_owned(),
            request: "PING",
            source: io::Error::from(io::ErrorKind::BrokenPipe),
        };
        assert_eq!(gone.kind(), ErrorKind::Disconnected);
    }

    #[test]
    fn config_defaults_and_unknown_fields() {
        let config: SerialBoardConfig =
            serde_json::from_str(r#"{"path": "/dev/ttyACM0"}"#).expect("valid config");
        assert_eq!(config, SerialBoardConfig::new("/dev/ttyACM0"));
        assert_eq!(config.baud_rate, 115_200);
        let tuned: SerialBoardConfig = serde_json::from_str(
            r#"{"path": "/dev/ttyUSB1", "baud_rate": 57600, "max_attempts": 1}"#,
        )
        .expect("valid config");
        assert_eq!(tuned.baud_rate, 57_600);
        assert_eq!(tuned.max_attempts, 1);
        let err =
            serde_json::from_str::<SerialBoardConfig>(r#"{"path": "/dev/ttyACM0", "baud": 9600}"#)
                .expect_err("unknown field must be refused");
        assert!(err.to_string().contains("baud"), "{err}");
    }
}
