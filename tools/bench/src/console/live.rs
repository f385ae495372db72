//! A client of the console's push connection (`/api/live`, a WebSocket): tungstenite over a
//! TCP socket bound to a chosen loopback address. 127.0.0.0/8 is all loopback on Linux, so
//! each kind of client can come from an address of its own, as devices on the field network
//! do. Used by the benchmark and by the console's load test.

use serde_json::Value;
use std::io::ErrorKind;
use std::net::{Ipv4Addr, SocketAddr, TcpStream};
use std::time::Duration;
use tungstenite::{Message, WebSocket};

/// Why a push connection could not be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LiveError {
    /// The console answered the upgrade with this HTTP status.
    #[error("the console refused the push connection with HTTP {0}")]
    Refused(u16),
    /// The connection failed or closed.
    #[error("push connection: {0}")]
    Failed(String),
}

/// A TCP connection to `127.0.0.1:port` from `local` (any port); `receive_buffer` sets the
/// socket's receive buffer (a slow reader's is small).
pub fn connect_from(
    local: Ipv4Addr,
    port: u16,
    receive_buffer: Option<usize>,
) -> std::io::Result<TcpStream> {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None)?;
    if let Some(bytes) = receive_buffer {
        socket.set_recv_buffer_size(bytes)?;
    }
    socket.bind(&SocketAddr::from((local, 0)).into())?;
    socket.connect(&SocketAddr::from((Ipv4Addr::LOCALHOST, port)).into())?;
    Ok(socket.into())
}

/// One message from the console.
#[derive(Debug, Clone)]
pub enum Live {
    /// `{"type": "status", ...}`.
    Status(Value),
    /// `{"type": "answer", "id": K, ...}`.
    Answer(Value),
    /// Any other text message (clock readings).
    Other(Value),
    /// A camera view: its header and the JPEG.
    View { header: Value, jpeg: Vec<u8> },
}

/// An open push connection.
pub struct LiveClient {
    socket: WebSocket<TcpStream>,
}

/// Opens `/api/live?session=N` from `local`.
pub fn open_live(
    local: Ipv4Addr,
    port: u16,
    session: u64,
    receive_buffer: Option<usize>,
) -> Result<LiveClient, LiveError> {
    let failed = |error: &dyn std::fmt::Display| LiveError::Failed(error.to_string());
    let stream = connect_from(local, port, receive_buffer).map_err(|e| failed(&e))?;
    stream
        .set_read_timeout(Some(Duration::from_secs(20)))
        .map_err(|e| failed(&e))?;
    let url = format!("ws://127.0.0.1:{port}/api/live?session={session}");
    match tungstenite::client(url.as_str(), stream) {
        Ok((socket, _response)) => Ok(LiveClient { socket }),
        Err(tungstenite::HandshakeError::Failure(tungstenite::Error::Http(response))) => {
            Err(LiveError::Refused(response.status().as_u16()))
        }
        Err(error) => Err(failed(&error)),
    }
}

/// Splits a pushed view into its header and its JPEG.
pub fn parse_view(data: &[u8]) -> Result<(Value, &[u8]), LiveError> {
    let bad = || LiveError::Failed("malformed view message".to_owned());
    let length = u32::from_le_bytes(
        data.get(..4)
            .ok_or_else(bad)?
            .try_into()
            .map_err(|_| bad())?,
    ) as usize;
    let header_bytes = data.get(4..4 + length).ok_or_else(bad)?;
    let header = serde_json::from_slice(header_bytes).map_err(|_| bad())?;
    Ok((header, &data[4 + length..]))
}

impl LiveClient {
    /// The next message, waiting up to `timeout`; `None` when nothing came.
    pub fn next(&mut self, timeout: Duration) -> Result<Option<Live>, LiveError> {
        self.socket
            .get_ref()
            .set_read_timeout(Some(timeout.max(Duration::from_millis(1))))
            .map_err(|e| LiveError::Failed(e.to_string()))?;
        loop {
            match self.socket.read() {
                Ok(Message::Text(text)) => {
                    let value: Value = serde_json::from_str(text.as_str())
                        .map_err(|e| LiveError::Failed(e.to_string()))?;
                    return Ok(Some(match value["type"].as_str() {
                        Some("status") => Live::Status(value),
                        Some("answer") => Live::Answer(value),
                        _ => Live::Other(value),
                    }));
                }
                Ok(Message::Binary(data)) => {
                    let (header, jpeg) = parse_view(&data)?;
                    return Ok(Some(Live::View {
                        header,
                        jpeg: jpeg.to_vec(),
                    }));
                }
                Ok(Message::Close(_)) => {
                    return Err(LiveError::Failed("closed by the console".to_owned()));
                }
                Ok(_) => continue,
                Err(tungstenite::Error::Io(error))
                    if matches!(error.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) =>
                {
                    return Ok(None);
                }
                Err(error) => return Err(LiveError::Failed(error.to_string())),
            }
        }
    }

    /// Sends one JSON message.
    pub fn send(&mut self, value: &Value) -> Result<(), LiveError> {
        self.socket
            .send(Message::text(value.to_string()))
            .map_err(|e| LiveError::Failed(e.to_string()))
    }
}
