//! A small blocking HTTP/1.1 server on `std::net`: one thread per connection, keep-alive,
//! bounded request sizes, no TLS. Enough for a handful of operator pages on the robot's
//! network; nothing here is downloaded or built at run time.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

/// Longest request line or header line, bytes.
const MAX_LINE_BYTES: usize = 8 * 1024;
/// Most header lines of one request.
const MAX_HEADERS: usize = 64;
/// Largest request body, bytes.
const MAX_BODY_BYTES: usize = 16 * 1024;
/// Connections served at once; more are answered 503 and closed.
const MAX_CONNECTIONS: usize = 32;
/// An idle keep-alive connection is closed after this long.
const IDLE_TIMEOUT: Duration = Duration::from_secs(30);

/// One request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    pub method: String,
    /// The path without the query.
    pub path: String,
    /// The query string (after `?`), possibly empty.
    pub query: String,
    /// Header names in lowercase.
    pub headers: Vec<(String, String)>,
    pub body: Vec<u8>,
    /// The peer.
    pub peer: Option<SocketAddr>,
}

impl Request {
    /// The value of query parameter `name`, if present.
    pub fn query_param(&self, name: &str) -> Option<&str> {
        self.query.split('&').find_map(|pair| {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            (key == name).then_some(value)
        })
    }

    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(key, _)| key == name)
            .map(|(_, value)| value.as_str())
    }
}

/// One response.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Response {
    pub status: u16,
    pub content_type: &'static str,
    pub headers: Vec<(&'static str, String)>,
    pub body: Arc<[u8]>,
}

impl Response {
    pub fn new(status: u16, content_type: &'static str, body: impl Into<Arc<[u8]>>) -> Self {
        Self {
            status,
            content_type,
            headers: Vec::new(),
            body: body.into(),
        }
    }

    /// A JSON body.
    pub fn json(status: u16, text: impl Into<Arc<[u8]>>) -> Self {
        Self::new(status, "application/json", text)
    }

    /// A plain-text error.
    pub fn text(status: u16, text: &str) -> Self {
        Self::new(status, "text/plain; charset=utf-8", text.as_bytes())
    }

    pub fn with_header(mut self, name: &'static str, value: String) -> Self {
        self.headers.push((name, value));
        self
    }
}

/// Why a request could not be read.
#[derive(Debug, thiserror::Error)]
pub enum HttpError {
    #[error("connection: {0}")]
    Io(#[from] std::io::Error),
    #[error("bad request: {0}")]
    Bad(&'static str),
}

fn reason_phrase(status: u16) -> &'static str {
    match status {
        200 => "OK",
        204 => "No Content",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        413 => "Payload Too Large",
        503 => "Service Unavailable",
        504 => "Gateway Timeout",
        _ => "Status",
    }
}

fn read_line(reader: &mut impl BufRead, line: &mut String) -> Result<usize, HttpError> {
    line.clear();
    let read = reader
        .by_ref()
        .take(MAX_LINE_BYTES as u64 + 1)
        .read_line(line)?;
    if line.len() > MAX_LINE_BYTES {
        return Err(HttpError::Bad("line too long"));
    }
    Ok(read)
}

/// Reads one request; `None` when the peer closed the connection between requests.
pub fn read_request(
    reader: &mut impl BufRead,
    peer: Option<SocketAddr>,
) -> Result<Option<Request>, HttpError> {
    let mut line = String::new();
    if read_line(reader, &mut line)? == 0 {
        return Ok(None);
    }
    let mut parts = line.split_whitespace();
    let (Some(method), Some(target), Some(version)) = (parts.next(), parts.next(), parts.next())
    else {
        return Err(HttpError::Bad("request line"));
    };
    if !version.starts_with("HTTP/1.") {
        return Err(HttpError::Bad("not HTTP/1.x"));
    }
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let mut request = Request {
        method: method.to_owned(),
        path: path.to_owned(),
        query: query.to_owned(),
        headers: Vec::new(),
        body: Vec::new(),
        peer,
    };
    loop {
        if read_line(reader, &mut line)? == 0 {
            return Err(HttpError::Bad("headers cut short"));
        }
        let text = line.trim_end();
        if text.is_empty() {
            break;
        }
        if request.headers.len() >= MAX_HEADERS {
            return Err(HttpError::Bad("too many headers"));
        }
        let (name, value) = text.split_once(':').ok_or(HttpError::Bad("header"))?;
        request
            .headers
            .push((name.trim().to_ascii_lowercase(), value.trim().to_owned()));
    }
    let length: usize = match request.header("content-length") {
        Some(text) => text.parse().map_err(|_| HttpError::Bad("content-length"))?,
        None => 0,
    };
    if length > MAX_BODY_BYTES {
        return Err(HttpError::Bad("body too large"));
    }
    request.body.resize(length, 0);
    reader.read_exact(&mut request.body)?;
    Ok(Some(request))
}

/// Writes `response`.
pub fn write_response(
    stream: &mut impl Write,
    response: &Response,
    keep_alive: bool,
) -> std::io::Result<()> {
    let mut head = format!(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: {}\r\n",
        response.status,
        reason_phrase(response.status),
        response.content_type,
        response.body.len(),
        if keep_alive { "keep-alive" } else { "close" }
    );
    for (name, value) in &response.headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    head.push_str("\r\n");
    stream.write_all(head.as_bytes())?;
    stream.write_all(&response.body)?;
    stream.flush()
}

/// The handler of every request.
pub type Handler = Arc<dyn Fn(&Request) -> Response + Send + Sync>;

fn serve_connection(stream: TcpStream, handler: &Handler) {
    let peer = stream.peer_addr().ok();
    if let Err(error) = stream.set_read_timeout(Some(IDLE_TIMEOUT)) {
        tracing::debug!(%error, "read timeout not set");
    }
    let _ = stream.set_nodelay(true);
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(stream);
    loop {
        let request = match read_request(&mut reader, peer) {
            Ok(Some(request)) => request,
            Ok(None) => return,
            Err(HttpError::Io(error)) => {
                tracing::trace!(%error, "connection ended");
                return;
            }
            Err(error) => {
                tracing::debug!(%error, ?peer, "bad request");
                let _ =
                    write_response(&mut writer, &Response::text(400, &error.to_string()), false);
                return;
            }
        };
        let keep_alive = request
            .header("connection")
            .is_none_or(|value| !value.eq_ignore_ascii_case("close"));
        let response = handler(&request);
        tracing::trace!(method = %request.method, path = %request.path, status = response.status, "request");
        if write_response(&mut writer, &response, keep_alive).is_err() || !keep_alive {
            return;
        }
    }
}

/// Serves `listener` until `stop` is set (and the listener is woken by a connection).
pub fn serve(listener: TcpListener, handler: Handler, stop: Arc<AtomicBool>) {
    let active = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        if stop.load(Ordering::Acquire) {
            break;
        }
        let mut stream = match stream {
            Ok(stream) => stream,
            Err(error) => {
                tracing::warn!(%error, "accept failed");
                continue;
            }
        };
        if active.load(Ordering::Acquire) >= MAX_CONNECTIONS {
            let _ = write_response(
                &mut stream,
                &Response::text(503, "too many connections"),
                false,
            );
            continue;
        }
        active.fetch_add(1, Ordering::AcqRel);
        let handler = handler.clone();
        let active_in_thread = active.clone();
        let spawned = std::thread::Builder::new()
            .name("console-http".to_owned())
            .spawn(move || {
                serve_connection(stream, &handler);
                active_in_thread.fetch_sub(1, Ordering::AcqRel);
            });
        if let Err(error) = spawned {
            active.fetch_sub(1, Ordering::AcqRel);
            tracing::warn!(%error, "connection thread not started");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_with_query_headers_and_body() {
        let text = b"POST /api/command?x=1&after=42 HTTP/1.1\r\nHost: a\r\nContent-Length: 4\r\n\r\nbodyGET / HTTP/1.1\r\n\r\n";
        let mut reader = BufReader::new(&text[..]);
        let first = read_request(&mut reader, None)
            .expect("read")
            .expect("request");
        assert_eq!(first.method, "POST");
        assert_eq!(first.path, "/api/command");
        assert_eq!(first.query_param("after"), Some("42"));
        assert_eq!(first.query_param("y"), None);
        assert_eq!(first.body, b"body");
        let second = read_request(&mut reader, None)
            .expect("read")
            .expect("request");
        assert_eq!(second.path, "/");
        assert!(read_request(&mut reader, None).expect("read").is_none());
    }

    #[test]
    fn oversized_or_malformed_requests_are_refused() {
        let big = format!(
            "POST / HTTP/1.1\r\nContent-Length: {}\r\n\r\n",
            MAX_BODY_BYTES + 1
        );
        assert!(matches!(
            read_request(&mut BufReader::new(big.as_bytes()), None),
            Err(HttpError::Bad("body too large"))
        ));
        assert!(matches!(
            read_request(&mut BufReader::new(&b"GARBAGE\r\n\r\n"[..]), None),
            Err(HttpError::Bad(_))
        ));
        let long = format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(MAX_LINE_BYTES + 10));
        assert!(read_request(&mut BufReader::new(long.as_bytes()), None).is_err());
    }

    #[test]
    fn responses_carry_length_and_connection() {
        let mut out = Vec::new();
        let response = Response::json(200, &b"{}"[..]).with_header("X-Frame-Seq", "3".to_owned());
        write_response(&mut out, &response, true).expect("write");
        let text = String::from_utf8(out).expect("utf-8");
        assert!(text.starts_with("HTTP/1.1 200 OK\r\n"));
        assert!(text.contains("Content-Length: 2\r\n"));
        assert!(text.contains("X-Frame-Seq: 3\r\n"));
        assert!(text.ends_with("\r\n\r\n{}"));
    }
}
