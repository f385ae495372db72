//! One plain HTTP/1.1 request to a local server (`Connection: close`, the body read to the end),
//! for the console's routes and Chromium's DevTools list.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// `method path` on `127.0.0.1:port` with an optional JSON body; the status and the body.
pub fn request(
    port: u16,
    method: &str,
    path: &str,
    body: Option<&str>,
) -> Result<(u16, Vec<u8>), String> {
    let mut stream =
        TcpStream::connect(("127.0.0.1", port)).map_err(|e| format!("connect :{port}: {e}"))?;
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .map_err(|e| e.to_string())?;
    let body = body.unwrap_or("");
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    );
    stream
        .write_all(head.as_bytes())
        .map_err(|e| format!("{method} {path}: {e}"))?;
    let mut response = Vec::new();
    stream
        .read_to_end(&mut response)
        .map_err(|e| format!("{method} {path}: {e}"))?;
    let split = response
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .ok_or_else(|| format!("{method} {path}: no response head"))?;
    let head = String::from_utf8_lossy(&response[..split]).to_ascii_lowercase();
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| format!("{method} {path}: no status"))?;
    if head.contains("transfer-encoding: chunked") {
        return Err(format!(
            "{method} {path}: chunked answers are not read here"
        ));
    }
    Ok((status, response[split + 4..].to_vec()))
}

/// `GET path` as JSON, `None` unless it answers 200 with JSON.
pub fn get_json(port: u16, path: &str) -> Option<serde_json::Value> {
    let (status, body) = request(port, "GET", path, None).ok()?;
    (status == 200).then(|| serde_json::from_slice(&body).ok())?
}
