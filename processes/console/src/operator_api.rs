//! The operator's requests, whichever way they come (a page's push connection or a plain
//! `POST`): a command goes to the executive on its lane (the e-stop on its own) and its answer
//! comes back as JSON; a mark goes on `operator/mark`. Both answer with an HTTP-like status
//! and a JSON body.

use std::net::IpAddr;
use std::time::Duration;

use harvest_operator::Command;
use harvest_operator::request::CommandRequest;
use serde::Deserialize;
use serde_json::{Value, json};

use crate::command_lane::{LaneAnswer, LaneCommand};
use crate::shared::Shared;

/// Longest mark text, bytes (the channel's capacity).
const MARK_TEXT_BYTES: usize = harvest_ipc::payloads::operator_mark::MARK_TEXT_BYTES;

/// A command as the page sends it (the e-stop needs no token).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PostedCommand {
    #[serde(default)]
    pub token: String,
    pub session: u64,
    pub command: CommandRequest,
}

/// A mark as the page sends it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PostedMark {
    #[serde(default)]
    pub text: String,
}

/// The client label the executive shows for a page.
pub fn client_label(peer: Option<IpAddr>) -> String {
    format!(
        "console {}",
        peer.map_or_else(|| "?".to_owned(), |peer| peer.to_string())
    )
}

/// Sends `posted` to the executive and waits (bounded) for its answer.
pub async fn command(shared: &Shared, posted: PostedCommand, peer: Option<IpAddr>) -> (u16, Value) {
    let command = match posted.command.to_command() {
        Ok(command) => command,
        Err(error) => {
            return (
                400,
                json!({"accepted": false, "refusal": "UnknownCommand", "reason": error.to_string()}),
            );
        }
    };
    let message = LaneCommand {
        command,
        session: posted.session,
        token: posted.token,
        client: client_label(peer),
    };
    let lane = if command == Command::EmergencyStop {
        &shared.estop_lane
    } else {
        &shared.command_lane
    };
    let answer = lane.submit(message);
    // The lane answers within its acknowledgement timeout once it takes the command; the
    // margin covers a command waiting behind another one on the command lane.
    let limit = 2 * shared.ack_timeout + Duration::from_millis(500);
    match tokio::time::timeout(limit, answer).await {
        Ok(Ok(LaneAnswer::Ack(answer))) => (
            200,
            json!({
                "accepted": answer.accepted,
                "reason": answer.reason,
                "refusal": answer.refusal,
                "mode": answer.mode,
                "motion_duration_ms": answer.motion_duration_ms,
            }),
        ),
        Ok(Ok(LaneAnswer::Unreachable(problem))) => (
            503,
            json!({"accepted": false, "unreachable": true, "reason": format!(
                "the console cannot reach the executive: {problem}"
            )}),
        ),
        Ok(Ok(LaneAnswer::NoAnswer)) | Ok(Err(_)) | Err(_) => (
            504,
            json!({"accepted": false, "reason": format!(
                "sent; no answer from the executive within {} ms (is it running?)",
                shared.ack_timeout.as_millis()
            )}),
        ),
    }
}

/// A command's JSON body, parsed; a bad one is answered 400.
pub fn parse_command(body: &[u8]) -> Result<PostedCommand, (u16, Value)> {
    serde_json::from_slice(body).map_err(|error| {
        (
            400,
            json!({"accepted": false, "reason": format!("bad request: {error}")}),
        )
    })
}

/// Publishes an operator mark (no token: a mark commands nothing).
pub async fn mark(shared: &Shared, posted: PostedMark, peer: Option<IpAddr>) -> (u16, Value) {
    let mut text = posted.text.trim().to_owned();
    if text.is_empty() {
        text = "operator mark (console)".to_owned();
    }
    if text.len() > MARK_TEXT_BYTES {
        return (
            400,
            json!({"accepted": false, "reason": format!(
                "a mark holds at most {MARK_TEXT_BYTES} bytes of text"
            )}),
        );
    }
    let Some(marks) = &shared.marks else {
        return (
            503,
            json!({"accepted": false, "reason": "marks are not carried over the remote link: make them on the robot's console or with `harvest ctl mark` there"}),
        );
    };
    let answer = marks.submit(text.clone(), client_label(peer));
    match tokio::time::timeout(Duration::from_secs(5), answer).await {
        Ok(Ok(Ok(marked_ns))) => (
            200,
            json!({"accepted": true, "reason": format!("marked: {text}"), "marked_ns": marked_ns}),
        ),
        Ok(Ok(Err(problem))) => (503, json!({"accepted": false, "reason": problem})),
        Ok(Err(_)) | Err(_) => (
            504,
            json!({"accepted": false, "reason": "the mark was not sent in time"}),
        ),
    }
}
