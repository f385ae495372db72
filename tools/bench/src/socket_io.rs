//! Reading and writing Unix stream sockets without losing bytes across timeouts.

use crate::error::BenchError;
use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::Path;

/// Fills `buf` from `stream`. When no byte is available (non-blocking socket, or a read timeout
/// expired) `on_idle` is called, which spins or checks the peer and may give up. Unlike
/// `read_exact`, bytes read before a timeout are kept.
pub fn read_full(
    stream: &mut UnixStream,
    buf: &mut [u8],
    what: &'static str,
    path: &Path,
    on_idle: &mut dyn FnMut() -> Result<(), BenchError>,
) -> Result<(), BenchError> {
    let mut filled = 0;
    while filled < buf.len() {
        match stream.read(&mut buf[filled..]) {
            Ok(0) => {
                return Err(BenchError::SocketClosed {
                    what,
                    path: path.to_owned(),
                });
            }
            Ok(read) => filled += read,
            Err(error) if matches!(error.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                on_idle()?
            }
            Err(error) if error.kind() == ErrorKind::Interrupted => {}
            Err(source) => {
                return Err(BenchError::Socket {
                    what,
                    path: path.to_owned(),
                    source,
                });
            }
        }
    }
    Ok(())
}

/// Writes all of `bytes` (blocking socket).
pub fn write_all(
    stream: &mut UnixStream,
    bytes: &[u8],
    what: &'static str,
    path: &Path,
) -> Result<(), BenchError> {
    stream
        .write_all(bytes)
        .map_err(|source| match source.kind() {
            ErrorKind::BrokenPipe | ErrorKind::ConnectionReset => BenchError::SocketClosed {
                what,
                path: path.to_owned(),
            },
            _ => BenchError::Socket {
                what,
                path: path.to_owned(),
                source,
            },
        })
}

/// Wraps an I/O error of a socket operation.
pub fn socket_error(what: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> BenchError {
    let path = path.to_owned();
    move |source| BenchError::Socket { what, path, source }
}
