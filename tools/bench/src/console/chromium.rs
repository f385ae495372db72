//! Debian's Chromium, headless, driven over its DevTools protocol (a WebSocket to the page's
//! target): the benchmark evaluates JavaScript in the page (reads the page's own figures,
//! clicks its buttons). Nothing downloads a browser.

use serde_json::{Value, json};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tungstenite::{Message, WebSocket};

use super::http_client;

/// A headless Chromium showing one page.
pub struct Chromium {
    child: Child,
    profile: PathBuf,
    socket: WebSocket<TcpStream>,
    next_id: u64,
}

fn free_port() -> Result<u16, String> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").map_err(|e| e.to_string())?;
    Ok(listener.local_addr().map_err(|e| e.to_string())?.port())
}

impl Chromium {
    /// Starts `binary` headless on `url` with a fresh profile and connects to the page.
    pub fn start(binary: &Path, url: &str) -> Result<Self, String> {
        let port = free_port()?;
        let profile = std::env::temp_dir().join(format!("harvest-bench-chromium-{port}"));
        let child = Command::new(binary)
            .args([
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-dev-shm-usage",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-background-timer-throttling",
                "--disable-renderer-backgrounding",
                "--window-size=1700,1050",
                "--remote-allow-origins=*",
            ])
            .arg(format!("--remote-debugging-port={port}"))
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(url)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("{}: {e} (apt-get install chromium)", binary.display()))?;
        let deadline = Instant::now() + Duration::from_secs(30);
        let target = loop {
            let page = http_client::get_json(port, "/json/list").and_then(|list| {
                list.as_array()?
                    .iter()
                    .find(|t| t["type"] == "page")
                    .and_then(|t| t["webSocketDebuggerUrl"].as_str().map(str::to_owned))
            });
            if let Some(page) = page {
                break page;
            }
            if Instant::now() > deadline {
                return Err("Chromium's DevTools did not come up within 30 s".to_owned());
            }
            std::thread::sleep(Duration::from_millis(200));
        };
        let stream = TcpStream::connect(("127.0.0.1", port)).map_err(|e| e.to_string())?;
        stream
            .set_read_timeout(Some(Duration::from_secs(30)))
            .map_err(|e| e.to_string())?;
        let (socket, _) = tungstenite::client(target.as_str(), stream)
            .map_err(|e| format!("DevTools connection: {e}"))?;
        Ok(Self {
            child,
            profile,
            socket,
            next_id: 1,
        })
    }

    /// Evaluates `expression` in the page (promises awaited); its value as JSON.
    pub fn evaluate(&mut self, expression: &str) -> Result<Value, String> {
        let id = self.next_id;
        self.next_id += 1;
        let call = json!({"id": id, "method": "Runtime.evaluate", "params": {
            "expression": expression, "returnByValue": true, "awaitPromise": true}});
        self.socket
            .send(Message::text(call.to_string()))
            .map_err(|e| format!("DevTools: {e}"))?;
        loop {
            let message = self.socket.read().map_err(|e| format!("DevTools: {e}"))?;
            let Message::Text(text) = message else {
                continue;
            };
            let answer: Value = serde_json::from_str(text.as_str()).map_err(|e| e.to_string())?;
            if answer["id"] != id {
                continue;
            }
            if let Some(exception) = answer["result"].get("exceptionDetails") {
                return Err(format!("{expression}: {exception}"));
            }
            return Ok(answer["result"]["result"]["value"].clone());
        }
    }
}

impl Drop for Chromium {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}
