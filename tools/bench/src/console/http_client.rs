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
    // Read the head, then the body by its Content-Length (Chromium's DevTools keeps the
    // connection open whatever the request asks); to the end where there is no length.
    let mut response = Vec::new();
    let mut chunk = [0u8; 16 * 1024];
    let split = loop {
        if let Some(split) = response.windows(4).position(|w| w == b"\r\n\r\n") {
            break split;
        }
        let read = stream
            .read(&mut chunk)
            .map_err(|e| format!("{method} {path}: {e}"))?;
        if read == 0 {
            return Err(format!("{method} {path}: no response head"));
        }
        response.extend_from_slice(&chunk[..read]);
    };
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
    let content_length = head.lines().find_map(|line| {
        let (name, value) = line.split_once(':')?;
        (name.trim() == "content-length")
            .then(|| value.trim().parse::<usize>().ok())
            .flatten()
    });
    let mut body = response.split_off(split + 4);
    match content_length {
        Some(length) => {
            while body.len() < length {
                let read = stream
                    .read(&mut chunk)
                    .map_err(|e| format!("{method} {path}: {e}"))?;
                if read == 0 {
                    return Err(format!(
                        "{method} {path}: the body ended at {} of {length} bytes",
                        body.len()
                    ));
                }
                body.extend_from_slice(&chunk[..read]);
            }
            body.truncate(length);
        }
        None => {
            stream
                .read_to_end(&mut body)
                .map_err(|e| format!("{method} {path}: {e}"))?;
        }
    }
    Ok((status, body))
}

/// `GET path` as JSON, `None` unless it answers 200 with JSON.
pub fn get_json(port: u16, path: &str) -> Option<serde_json::Value> {
    let (status, body) = request(port, "GET", path, None).ok()?;
    (status == 200).then(|| serde_json::from_slice(&body).ok())?
}
