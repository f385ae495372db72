//! The station's request and the robot's reply, as JSON on the command and e-stop queries.
//!
//! Request: `{"session": 17, "token": "<32 hex>", "client": "station ana", "command":
//! {"command": "jog", "arm": 1, "joint": "theta", "delta": 0.05}}` (the command object is the
//! console's [`CommandRequest`]). The e-stop lane accepts an empty payload.
//!
//! Reply: `{"accepted": true, "by": "executive", "reason": "...", "mode": "manual",
//! "motion_duration_ms": 800}`; a refusal names who refused (`remote`: the bridge's own checks,
//! nothing reached the executive; `executive`: the executive's answer) and the refusal code.

use harvest_operator::request::CommandRequest;
use serde::{Deserialize, Serialize};

/// Longest request accepted, bytes.
pub const MAX_REQUEST_BYTES: usize = 1024;

/// One operator command from the station.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RemoteRequest {
    /// The station's session (non-zero; the same for the commands and heartbeats of one
    /// controlling client).
    pub session: u64,
    /// The robot's control token (none for an e-stop).
    #[serde(default)]
    pub token: Option<String>,
    /// Who asks, in a few words.
    pub client: String,
    pub command: CommandRequest,
}

/// Who answered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Answerer {
    /// The bridge refused before the executive saw it.
    Remote,
    /// The executive's own answer.
    Executive,
}

/// The answer to one request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RemoteReply {
    pub accepted: bool,
    pub by: Answerer,
    /// The refusal's code name (`NoToken`, `RateLimited`, ...), none when accepted.
    #[serde(default)]
    pub refusal: Option<String>,
    pub reason: String,
    /// The mode after the command (executive answers).
    #[serde(default)]
    pub mode: Option<String>,
    #[serde(default)]
    pub motion_duration_ms: u32,
}

impl RemoteReply {
    /// A refusal by the bridge.
    pub fn refused_by_remote(refusal: &str, reason: String) -> Self {
        Self {
            accepted: false,
            by: Answerer::Remote,
            refusal: Some(refusal.to_owned()),
            reason,
            mode: None,
            motion_duration_ms: 0,
        }
    }

    pub fn to_json(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }
}

/// The session id the executive sees for a station's session: kept apart from the ids of local
/// clients (FNV-1a of `remote:<session>`), never 0.
pub fn forwarded_session(station_session: u64) -> u64 {
    format!("remote:{station_session}")
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |hash, byte| {
            (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        })
        .max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_and_replies_read_back() {
        let text = r#"{"session":17,"token":"ab","client":"station","command":{"command":"jog","arm":1,"joint":"theta","delta":0.05}}"#;
        let request: RemoteRequest = serde_json::from_str(text).expect("request");
        assert_eq!(request.session, 17);
        assert_eq!(request.command.command, "jog");
        let reply = RemoteReply::refused_by_remote("RateLimited", "too many".to_owned());
        let back: RemoteReply = serde_json::from_slice(&reply.to_json()).expect("reply");
        assert_eq!(back, reply);
        assert!(
            serde_json::from_str::<RemoteRequest>(
                r#"{"session":1,"client":"x","command":{"command":"stop"},"extra":1}"#
            )
            .is_err()
        );
        assert_ne!(forwarded_session(1), 1);
        assert_ne!(forwarded_session(1), forwarded_session(2));
    }
}
