//! Byte-stream framing for the valve board protocol: turns the raw bytes of a serial line into
//! frame contents, dropping noise and resynchronising on the next `$`.
//!
//! Rules (see `hw/VALVE_PROTOCOL.md`, "Framing and resynchronisation"):
//! - bytes outside a frame are discarded (counted in [`LineAssembler::discarded_bytes`]);
//! - `$` starts a frame; a `$` inside a frame abandons the partial one (reported as
//!   [`AssemblyError::Truncated`]) and starts anew, so a frame cut by a board reset or a lost
//!   byte never swallows the next one;
//! - `\n` ends a frame; `\r` inside a frame is ignored;
//! - a byte outside printable ASCII inside a frame abandons it ([`AssemblyError::BadByte`]);
//! - a frame longer than [`MAX_FRAME_LEN`] is abandoned ([`AssemblyError::Overlong`]) and the
//!   rest of it skipped up to the next `\n` or `$`.

use super::protocol::{FRAME_END, FRAME_START, MAX_FRAME_LEN};

/// Why bytes that started as a frame did not make a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AssemblyError {
    /// A new `$` arrived before the frame's `\n`.
    #[error("frame cut after {len} bytes by a new start of frame")]
    Truncated {
        /// Bytes of the abandoned frame.
        len: usize,
    },
    /// The frame exceeded [`MAX_FRAME_LEN`] bytes.
    #[error("frame longer than {limit} bytes")]
    Overlong {
        /// The limit.
        limit: usize,
    },
    /// A byte outside printable ASCII arrived inside a frame.
    #[error("byte 0x{byte:02X} inside a frame")]
    BadByte {
        /// The offending byte.
        byte: u8,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    /// Waiting for `$`.
    Hunting,
    /// Inside a frame.
    InFrame,
    /// Skipping the rest of an overlong frame.
    SkippingOverlong,
}

/// Assembles frames byte by byte with a fixed buffer (no allocation).
#[derive(Debug, Clone)]
pub struct LineAssembler {
    buf: [u8; MAX_FRAME_LEN],
    len: usize,
    state: State,
    discarded_bytes: u64,
}

impl Default for LineAssembler {
    fn default() -> Self {
        LineAssembler::new()
    }
}

impl LineAssembler {
    /// An empty assembler, waiting for `$`.
    pub fn new() -> LineAssembler {
        LineAssembler {
            buf: [0; MAX_FRAME_LEN],
            len: 0,
            state: State::Hunting,
            discarded_bytes: 0,
        }
    }

    /// Bytes dropped outside any frame (noise between lines) since creation.
    pub fn discarded_bytes(&self) -> u64 {
        self.discarded_bytes
    }

    /// Forget any partial frame (after reopening the port, for instance).
    pub fn reset(&mut self) {
        self.len = 0;
        self.state = State::Hunting;
    }

    /// Feed one byte. Returns `Some(Ok(content))` when a frame completes (the bytes between
    /// `$` and `\n`, without `\r`; valid until the next call), `Some(Err(_))` when a started
    /// frame is abandoned, `None` otherwise.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], AssemblyError>> {
        match self.state {
            State::Hunting => {
                if byte == FRAME_START {
                    self.start_frame();
                } else {
                    self.discarded_bytes += 1;
                }
                None
            }
            State::SkippingOverlong => {
                if byte == FRAME_START {
                    self.start_frame();
                } else {
                    self.discarded_bytes += 1;
                    if byte == FRAME_END {
                        self.state = State::Hunting;
                    }
                }
                None
            }
            State::InFrame => match byte {
                FRAME_END => {
                    self.state = State::Hunting;
                    Some(Ok(&self.buf[..self.len]))
                }
                FRAME_START => {
                    let len = self.len;
                    self.start_frame();
                    Some(Err(AssemblyError::Truncated { len }))
                }
                b'\r' => None,
                0x20..=0x7E => {
                    if self.len == MAX_FRAME_LEN {
                        self.state = State::SkippingOverlong;
                        return Some(Err(AssemblyError::Overlong {
                            limit: MAX_FRAME_LEN,
                        }));
                    }
                    self.buf[self.len] = byte;
                    self.len += 1;
                    None
                }
                _ => {
                    self.state = State::Hunting;
                    Some(Err(AssemblyError::BadByte { byte }))
                }
            },
        }
    }

    fn start_frame(&mut self) {
        self.len = 0;
        self.state = State::InFrame;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::valve_board::protocol::{Request, decode_frame, decode_request, encode_request};

    /// Feed `bytes`, collecting completed lines (as strings) and errors in order.
    fn feed(asm: &mut LineAssembler, bytes: &[u8]) -> Vec<Result<String, AssemblyError>> {
        let mut events = Vec::new();
        for &b in bytes {
            if let Some(event) = asm.push(b) {
                events.push(event.map(|line| String::from_utf8_lossy(line).into_owned()));
            }
        }
        events
    }

    #[test]
    fn clean_lines_split_on_newline_and_crlf() {
        let mut asm = LineAssembler::new();
        let events = feed(&mut asm, b"$A*1*00\n$B*2*00\r\n");
        assert_eq!(
            events,
            vec![Ok("A*1*00".to_owned()), Ok("B*2*00".to_owned())]
        );
        assert_eq!(asm.discarded_bytes(), 0);
    }

    #[test]
    fn garbage_between_lines_is_dropped_and_counted() {
        let mut asm = LineAssembler::new();
        let mut stream = b"\x00\xFF noise\n\n".to_vec();
        let mut frame = Vec::new();
        encode_request(9, &Request::Pressures, &mut frame);
        stream.extend_from_slice(&frame);
        stream.extend_from_slice(b"\x07\x08junk");
        stream.extend_from_slice(&frame);
        let mut lines = 0;
        for &b in &stream {
            if let Some(Ok(line)) = asm.push(b) {
                let frame = decode_frame(line).expect("valid frame");
                assert_eq!(decode_request(frame.body), Ok(Request::Pressures));
                lines += 1;
            }
        }
        assert_eq!(lines, 2);
        assert_eq!(asm.discarded_bytes(), 10 + 6);
    }

    #[test]
    fn truncated_frame_resyncs_on_next_start() {
        let mut asm = LineAssembler::new();
        let events = feed(&mut asm, b"$OK PO$OK*1*00\n");
        assert_eq!(
            events,
            vec![
                Err(AssemblyError::Truncated { len: 5 }),
                Ok("OK*1*00".to_owned())
            ]
        );
    }

    #[test]
    fn overlong_frame_is_skipped_to_line_end() {
        let mut asm = LineAssembler::new();
        let mut stream = vec![b'$'];
        stream.extend(std::iter::repeat_n(b'x', MAX_FRAME_LEN + 50));
        stream.extend_from_slice(b"\n$OK*1*00\n");
        let events = feed(&mut asm, &stream);
        assert_eq!(
            events,
            vec![
                Err(AssemblyError::Overlong {
                    limit: MAX_FRAME_LEN
                }),
                Ok("OK*1*00".to_owned())
            ]
        );
        // Exactly the limit is still accepted.
        let mut exact = vec![b'$'];
        exact.extend(std::iter::repeat_n(b'y', MAX_FRAME_LEN));
        exact.push(b'\n');
        let events = feed(&mut asm, &exact);
        assert_eq!(events, vec![Ok("y".repeat(MAX_FRAME_LEN))]);
    }

    #[test]
    fn overlong_frame_resyncs_on_start_without_newline() {
        let mut asm = LineAssembler::new();
        let mut stream = vec![b'$'];
        stream.extend(std::iter::repeat_n(b'x', MAX_FRAME_LEN + 1));
        stream.extend_from_slice(b"$OK*1*00\n");
        let events = feed(&mut asm, &stream);
        assert_eq!(events.len(), 2);
        assert_eq!(events[1], Ok("OK*1*00".to_owned()));
    }

    #[test]
    fn control_byte_abandons_frame() {
        let mut asm = LineAssembler::new();
        let events = feed(&mut asm, b"$OK\x00PONG*1*00\n$OK*2*00\n");
        assert_eq!(
            events,
            vec![
                Err(AssemblyError::BadByte { byte: 0 }),
                Ok("OK*2*00".to_owned())
            ]
        );
    }

    #[test]
    fn reset_forgets_partial_frame() {
        let mut asm = LineAssembler::new();
        assert!(feed(&mut asm, b"$OK PARTIAL").is_empty());
        asm.reset();
        assert_eq!(feed(&mut asm, b"*1*00\n"), vec![]);
    }
}
