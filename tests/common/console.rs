//! The operator console as the tests reach it over HTTP: its status, commands posted as the page
//! posts them, the control token the stack wrote, and waiting for a console that serves.

use super::webdriver::http;
use serde_json::{Value, json};
use std::time::{Duration, Instant};

/// Calls `check` every 50 ms until it is true; fails naming `what` after `limit` (a watchdog,
/// not a timing requirement).
pub fn wait_until(what: &str, limit: Duration, mut check: impl FnMut() -> bool) {
    let deadline = Instant::now() + limit;
    while !check() {
        assert!(
            Instant::now() < deadline,
            "watchdog: {what} not seen within {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// `GET /api/status` as JSON, or `None` while the console does not answer 200.
pub fn status(port: u16) -> Option<Value> {
    let (code, body) = http(port, "GET", "/api/status", None).ok()?;
    (code == 200).then(|| serde_json::from_slice(&body).ok())?
}

/// Posts one command as the page does; returns the HTTP status and the JSON answer.
pub fn post_command(port: u16, token: &str, session: u64, command: Value) -> (u16, Value) {
    let body = json!({"token": token, "session": session, "command": command}).to_string();
    let (code, answer) = http(port, "POST", "/api/command", Some(&body)).expect("post");
    (code, serde_json::from_slice(&answer).expect("json answer"))
}

/// The control token `harvest up` wrote for `domain` (waits for the file).
pub fn control_token(domain: &str) -> String {
    let token_file = harvest_operator::token::token_path(domain);
    wait_until("the control token file", Duration::from_secs(20), || {
        token_file.exists()
    });
    harvest_operator::token::read_token_file(&token_file)
        .expect("token file")
        .as_str()
        .to_owned()
}

/// Waits until the console serves the harvesting mode, both arms and a camera view.
pub fn wait_for_harvesting_console(port: u16) {
    wait_until(
        "the console serving the mode, both arms and a camera view",
        Duration::from_secs(120),
        || {
            status(port).is_some_and(|s| {
                s["mode"]["name"] == "harvesting"
                    && s["arms"][0].is_object()
                    && s["arms"][1].is_object()
                    && s["view"].is_object()
            })
        },
    );
}
