//! The copying baseline: each message is encoded with the stack's codec (`Payload::encode`),
//! written to a Unix domain stream socket as `[length u64 LE][bytes]`, read into a buffer and
//! decoded (`Payload::decode_into`) into the receiver's own copy. Event mode blocks in `read`;
//! poll mode spins on a non-blocking socket.

use super::{OnMessage, ReceivePort, SendPort};
use crate::bench_payload::zeroed_box;
use crate::control::{HELLO_DATA, accept_stream};
use crate::error::BenchError;
use crate::message::{BenchMessage, Phase};
use crate::options::WakeMode;
use crate::sender_write::PayloadWriter;
use crate::socket_io::{read_full, socket_error, write_all};
use crate::watchdog::Watchdog;
use harvest_ipc::{Flow, MonotonicClock};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};

const WHAT: &str = "copying-baseline data";
/// Bytes of the length prefix.
const PREFIX_BYTES: usize = 8;

/// Encodes into a reused buffer and writes it.
pub struct CopySender<T: BenchMessage> {
    stream: UnixStream,
    path: PathBuf,
    message: Box<T>,
    buffer: Vec<u8>,
    next_seq: u64,
    payload: &'static str,
}

impl<T: BenchMessage> CopySender<T> {
    /// Opens the data connection to the receiver's listener at `path`.
    pub fn connect(path: &Path, payload: &'static str) -> Result<Self, BenchError> {
        let mut stream = UnixStream::connect(path).map_err(socket_error(WHAT, path))?;
        write_all(&mut stream, &[HELLO_DATA], WHAT, path)?;
        Ok(Self {
            stream,
            path: path.to_owned(),
            message: zeroed_box(),
            buffer: Vec::with_capacity(PREFIX_BYTES + 2 * std::mem::size_of::<T>()),
            next_seq: 1,
            payload,
        })
    }
}

impl<T: BenchMessage> SendPort<T> for CopySender<T> {
    fn send(&mut self, phase: Phase, writer: &mut PayloadWriter) -> Result<u64, BenchError> {
        let msg_seq = self.next_seq;
        let publish_ns = writer.write_stamped(&mut *self.message, msg_seq, phase);
        self.buffer.clear();
        self.buffer.extend_from_slice(&[0; PREFIX_BYTES]);
        self.message
            .encode(&mut self.buffer)
            .map_err(|source| BenchError::Codec {
                operation: "encode",
                payload: self.payload,
                source,
            })?;
        let length = (self.buffer.len() - PREFIX_BYTES) as u64;
        self.buffer[..PREFIX_BYTES].copy_from_slice(&length.to_le_bytes());
        write_all(&mut self.stream, &self.buffer, WHAT, &self.path)?;
        self.next_seq += 1;
        Ok(MonotonicClock::read_ns().saturating_sub(publish_ns))
    }
}

/// Reads, decodes into its own copy, hands the copy on.
pub struct CopyReceiver<T: BenchMessage> {
    stream: UnixStream,
    path: PathBuf,
    mode: WakeMode,
    message: Box<T>,
    buffer: Vec<u8>,
    payload: &'static str,
}

impl<T: BenchMessage> CopyReceiver<T> {
    /// Accepts the peer's data connection on `listener`.
    pub fn accept(
        listener: &UnixListener,
        path: &Path,
        mode: WakeMode,
        payload: &'static str,
        watchdog: &mut Watchdog,
    ) -> Result<Self, BenchError> {
        let stream = accept_stream(listener, path, WHAT, HELLO_DATA, watchdog)?;
        if mode == WakeMode::Poll {
            stream
                .set_nonblocking(true)
                .map_err(socket_error(WHAT, path))?;
        }
        Ok(Self {
            stream,
            path: path.to_owned(),
            mode,
            message: zeroed_box(),
            buffer: Vec::with_capacity(2 * std::mem::size_of::<T>()),
            payload,
        })
    }

    /// Largest encoded message accepted (encodings are at most a little larger than the type).
    fn max_frame_bytes() -> usize {
        2 * std::mem::size_of::<T>() + 4096
    }
}

impl<T: BenchMessage> ReceivePort<T> for CopyReceiver<T> {
    fn run_phase(
        &mut self,
        watchdog: &mut Watchdog,
        on_message: &mut OnMessage<'_, T>,
    ) -> Result<(), BenchError> {
        let poll = self.mode == WakeMode::Poll;
        let mut on_idle = || {
            if poll {
                std::hint::spin_loop();
                watchdog.poll_check()
            } else {
                // A read timed out: nothing arrived for a watch period.
                watchdog.check()
            }
        };
        loop {
            let mut prefix = [0u8; PREFIX_BYTES];
            read_full(
                &mut self.stream,
                &mut prefix,
                WHAT,
                &self.path,
                &mut on_idle,
            )?;
            let length = u64::from_le_bytes(prefix);
            let max = Self::max_frame_bytes();
            if length > max as u64 {
                return Err(BenchError::BadFrame {
                    path: self.path.clone(),
                    payload: self.payload,
                    length,
                    max,
                });
            }
            // Capacity was reserved up front: no allocation per message.
            self.buffer.resize(length as usize, 0);
            read_full(
                &mut self.stream,
                &mut self.buffer,
                WHAT,
                &self.path,
                &mut on_idle,
            )?;
            T::decode_into(&self.buffer, &mut self.message).map_err(|source| {
                BenchError::Codec {
                    operation: "decode",
                    payload: self.payload,
                    source,
                }
            })?;
            let recv_ns = MonotonicClock::read_ns();
            if on_message(&self.message, recv_ns)? == Flow::Stop {
                return Ok(());
            }
        }
    }
}
