//! The control connection between the receiving process and its peer: one byte per step.
//!
//! Peer: connect (`HELLO_CONTROL`; for the copying baseline also a data connection with
//! `HELLO_DATA`), open its sender, `READY`. Receiver: `GO_LATENCY`; then per stop-and-wait
//! message `ACK`; `GO_STREAM`; then `ACK` per streamed message (the peer keeps at most a window
//! of unacknowledged messages in flight); after the last one `END`; the peer answers with its
//! median send-call time (8 bytes, u64 little-endian nanoseconds) and exits.
//! The control connection only paces the run: it is never inside a measured interval.

use crate::error::BenchError;
use crate::socket_io::{read_full, socket_error, write_all};
use crate::watchdog::{WATCH_PERIOD, Watchdog};
use std::io::Read;
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

pub const HELLO_CONTROL: u8 = b'C';
pub const HELLO_DATA: u8 = b'D';
pub const READY: u8 = b'R';
pub const GO_LATENCY: u8 = b'L';
pub const ACK: u8 = b'A';
pub const GO_STREAM: u8 = b'S';
pub const END: u8 = b'E';

const WHAT: &str = "control";

/// One end of the control connection.
pub struct Control {
    stream: UnixStream,
    path: PathBuf,
}

impl Control {
    /// Peer side: connects and introduces itself.
    pub fn connect(path: &Path) -> Result<Self, BenchError> {
        let stream = UnixStream::connect(path).map_err(socket_error(WHAT, path))?;
        let mut control = Self {
            stream,
            path: path.to_owned(),
        };
        control.send(HELLO_CONTROL)?;
        Ok(control)
    }

    /// Receiver side: accepts the peer's control connection.
    pub fn accept(
        listener: &UnixListener,
        path: &Path,
        watchdog: &mut Watchdog,
    ) -> Result<Self, BenchError> {
        let stream = accept_stream(listener, path, WHAT, HELLO_CONTROL, watchdog)?;
        Ok(Self {
            stream,
            path: path.to_owned(),
        })
    }

    pub fn send(&mut self, byte: u8) -> Result<(), BenchError> {
        write_all(&mut self.stream, &[byte], WHAT, &self.path)
    }

    /// Peer side: sends one number (u64 little-endian).
    pub fn send_u64(&mut self, value: u64) -> Result<(), BenchError> {
        write_all(&mut self.stream, &value.to_le_bytes(), WHAT, &self.path)
    }

    /// Receiver side: reads one number sent with [`Self::send_u64`], watching the peer.
    pub fn read_u64_watched(&mut self, watchdog: &mut Watchdog) -> Result<u64, BenchError> {
        let mut bytes = [0u8; 8];
        read_full(&mut self.stream, &mut bytes, WHAT, &self.path, &mut || {
            watchdog.check()
        })?;
        Ok(u64::from_le_bytes(bytes))
    }

    /// Peer side: blocks for the next byte and checks it.
    pub fn expect(&mut self, expected: u8, context: &'static str) -> Result<(), BenchError> {
        let mut byte = [0u8];
        read_full(
            &mut self.stream,
            &mut byte,
            WHAT,
            &self.path,
            &mut || Ok(()),
        )?;
        check_byte(expected, byte[0], context)
    }

    /// Peer side: blocks until at least one byte arrives, reads at most `outstanding` bytes
    /// (so a following `END` stays unread), checks that all are `ACK`, and returns how many.
    pub fn read_acks(&mut self, outstanding: usize) -> Result<usize, BenchError> {
        let mut bytes = [0u8; 256];
        let wanted = outstanding.clamp(1, bytes.len());
        let read = loop {
            match self.stream.read(&mut bytes[..wanted]) {
                Ok(0) => {
                    return Err(BenchError::SocketClosed {
                        what: WHAT,
                        path: self.path.clone(),
                    });
                }
                Ok(read) => break read,
                Err(error) if error.kind() == std::io::ErrorKind::Interrupted => {}
                Err(source) => {
                    return Err(BenchError::Socket {
                        what: WHAT,
                        path: self.path.clone(),
                        source,
                    });
                }
            }
        };
        for &byte in &bytes[..read] {
            check_byte(ACK, byte, "acknowledgement of a streamed message")?;
        }
        Ok(read)
    }

    /// Receiver side: waits for the next byte while watching the peer.
    pub fn expect_watched(
        &mut self,
        expected: u8,
        context: &'static str,
        watchdog: &mut Watchdog,
    ) -> Result<(), BenchError> {
        let mut byte = [0u8];
        read_full(&mut self.stream, &mut byte, WHAT, &self.path, &mut || {
            watchdog.check()
        })?;
        check_byte(expected, byte[0], context)
    }
}

fn check_byte(expected: u8, got: u8, context: &'static str) -> Result<(), BenchError> {
    if got == expected {
        Ok(())
    } else {
        Err(BenchError::Protocol {
            expected: char::from(expected),
            got: char::from(got),
            context,
        })
    }
}

/// Accepts one connection that introduces itself with `hello`, watching the peer meanwhile.
/// The returned stream is blocking, with reads timing out after [`WATCH_PERIOD`].
pub fn accept_stream(
    listener: &UnixListener,
    path: &Path,
    what: &'static str,
    hello: u8,
    watchdog: &mut Watchdog,
) -> Result<UnixStream, BenchError> {
    listener
        .set_nonblocking(true)
        .map_err(socket_error(what, path))?;
    let mut stream = loop {
        match listener.accept() {
            Ok((stream, _)) => break stream,
            Err(error) if error.kind() == std::io::ErrorKind::WouldBlock => {
                watchdog.check()?;
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(error) if error.kind() == std::io::ErrorKind::Interrupted => {}
            Err(source) => {
                return Err(BenchError::Socket {
                    what,
                    path: path.to_owned(),
                    source,
                });
            }
        }
    };
    stream
        .set_nonblocking(false)
        .map_err(socket_error(what, path))?;
    stream
        .set_read_timeout(Some(WATCH_PERIOD))
        .map_err(socket_error(what, path))?;
    let mut byte = [0u8];
    read_full(&mut stream, &mut byte, what, path, &mut || watchdog.check())?;
    check_byte(hello, byte[0], "connection greeting")?;
    Ok(stream)
}
