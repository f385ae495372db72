//! What comes in from the station before the executive sees it. Only two keys answer: the
//! command key and the e-stop key (a query on any other key, a wildcard included, is refused as
//! unknown). On the command lane a request must be at most [`MAX_REQUEST_BYTES`], valid JSON of
//! [`RemoteRequest`] naming a known command with its arguments, from a non-zero session, and
//! within the rate limit (a burst of [`BURST`], then [`RATE_PER_S`] a second: heartbeats at
//! 10 Hz fit). The token is not checked here: the executive checks it and its answer goes back.
//!
//! An emergency stop is never refused by the gate: on the e-stop lane any payload (even none,
//! even malformed or oversized, which is counted) is a stop, and a stop on the command lane
//! skips the rate limit. A stop needs no authority and wins over every error.

use harvest_operator::Command;

use crate::keys::RobotKeys;
use crate::remote_request::{MAX_REQUEST_BYTES, RemoteRequest, forwarded_session};
use crate::token_bucket::TokenBucket;

/// Commands in a burst.
pub const BURST: u32 = 20;
/// Commands a second after a burst.
pub const RATE_PER_S: f64 = 20.0;
/// Longest client label forwarded, bytes.
const CLIENT_LABEL_BYTES: usize = 40;

/// A command to forward to the executive.
#[derive(Debug, Clone, PartialEq)]
pub struct Admitted {
    pub command: Command,
    /// The session the executive sees ([`forwarded_session`]).
    pub session: u64,
    /// As sent (empty: none).
    pub token: String,
    /// `remote <client>`.
    pub client: String,
}

/// Why a request went no further.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InboundRefusal {
    #[error("unknown key `{0}`: only the command and e-stop keys answer")]
    UnknownKey(String),
    #[error("request of {0} bytes is over the {MAX_REQUEST_BYTES}-byte limit")]
    Oversized(usize),
    #[error("malformed request: {0}")]
    Malformed(String),
    #[error("more than {BURST} commands in a burst or {RATE_PER_S} a second: refused")]
    RateLimited,
}

impl InboundRefusal {
    /// The code name in the reply.
    pub fn code(&self) -> &'static str {
        match self {
            Self::UnknownKey(_) => "UnknownKey",
            Self::Oversized(_) => "Oversized",
            Self::Malformed(_) => "Malformed",
            Self::RateLimited => "RateLimited",
        }
    }
}

/// Counts of what the gate saw (the process reports them in its heartbeat and log).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct InboundCounters {
    pub admitted: u64,
    pub unknown_key: u64,
    pub oversized: u64,
    pub malformed: u64,
    pub rate_limited: u64,
    /// E-stop requests whose payload was malformed or oversized (stopped all the same).
    pub estop_bad_payload: u64,
}

impl InboundCounters {
    /// Every refusal.
    pub fn refused(&self) -> u64 {
        self.unknown_key + self.oversized + self.malformed + self.rate_limited
    }
}

/// The gate of one robot (module docs).
#[derive(Debug, Clone)]
pub struct InboundGate {
    keys: RobotKeys,
    bucket: TokenBucket,
    counters: InboundCounters,
}

fn label(client: &str) -> String {
    let mut label = format!("remote {client}");
    if label.len() > CLIENT_LABEL_BYTES {
        let mut end = CLIENT_LABEL_BYTES;
        while !label.is_char_boundary(end) {
            end -= 1;
        }
        label.truncate(end);
    }
    label
}

impl InboundGate {
    pub fn new(keys: RobotKeys) -> Self {
        Self {
            keys,
            bucket: TokenBucket::new(BURST, RATE_PER_S),
            counters: InboundCounters::default(),
        }
    }

    pub fn counters(&self) -> InboundCounters {
        self.counters
    }

    /// Checks one query on `key` with `payload` at `now_ns`.
    pub fn admit(
        &mut self,
        key: &str,
        payload: &[u8],
        now_ns: u64,
    ) -> Result<Admitted, InboundRefusal> {
        let result = self.check(key, payload, now_ns);
        match &result {
            Ok(_) => self.counters.admitted += 1,
            Err(InboundRefusal::UnknownKey(_)) => self.counters.unknown_key += 1,
            Err(InboundRefusal::Oversized(_)) => self.counters.oversized += 1,
            Err(InboundRefusal::Malformed(_)) => self.counters.malformed += 1,
            Err(InboundRefusal::RateLimited) => self.counters.rate_limited += 1,
        }
        result
    }

    fn check(
        &mut self,
        key: &str,
        payload: &[u8],
        now_ns: u64,
    ) -> Result<Admitted, InboundRefusal> {
        if key == self.keys.estop() {
            return Ok(self.estop(payload));
        }
        if key != self.keys.command() {
            return Err(InboundRefusal::UnknownKey(key.chars().take(120).collect()));
        }
        if payload.len() > MAX_REQUEST_BYTES {
            return Err(InboundRefusal::Oversized(payload.len()));
        }
        let request: RemoteRequest = serde_json::from_slice(payload)
            .map_err(|e| InboundRefusal::Malformed(e.to_string()))?;
        let command = request
            .command
            .to_command()
            .map_err(|e| InboundRefusal::Malformed(e.to_string()))?;
        if request.session == 0 {
            return Err(InboundRefusal::Malformed("session 0".to_owned()));
        }
        if command != Command::EmergencyStop && !self.bucket.take(now_ns) {
            return Err(InboundRefusal::RateLimited);
        }
        Ok(Admitted {
            command,
            session: forwarded_session(request.session),
            token: request.token.unwrap_or_default(),
            client: label(&request.client),
        })
    }

    /// The e-stop lane: always a stop.
    fn estop(&mut self, payload: &[u8]) -> Admitted {
        let request = (!payload.is_empty() && payload.len() <= MAX_REQUEST_BYTES)
            .then(|| serde_json::from_slice::<RemoteRequest>(payload).ok())
            .flatten();
        if request.is_none() && !payload.is_empty() {
            self.counters.estop_bad_payload += 1;
        }
        Admitted {
            command: Command::EmergencyStop,
            session: forwarded_session(request.as_ref().map_or(0, |r| r.session)),
            token: String::new(),
            client: label(request.as_ref().map_or("station", |r| r.client.as_str())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot_name::RobotName;

    fn gate() -> InboundGate {
        InboundGate::new(RobotKeys::new(RobotName::parse("r1").expect("name")))
    }

    fn request(command: &str) -> Vec<u8> {
        format!(r#"{{"session":5,"token":"t","client":"ana","command":{{"command":"{command}"}}}}"#)
            .into_bytes()
    }

    #[test]
    fn good_requests_pass_and_bad_ones_are_counted() {
        let mut gate = gate();
        let admitted = gate
            .admit("harvest/v1/r1/command", &request("pause"), 0)
            .expect("pause");
        assert_eq!(admitted.command, Command::Pause);
        assert_eq!(admitted.client, "remote ana");
        assert_eq!(admitted.session, forwarded_session(5));
        assert!(matches!(
            gate.admit("harvest/v1/r1/*", &request("pause"), 0),
            Err(InboundRefusal::UnknownKey(_))
        ));
        assert!(matches!(
            gate.admit("harvest/v1/r2/command", &request("pause"), 0),
            Err(InboundRefusal::UnknownKey(_))
        ));
        assert!(matches!(
            gate.admit(
                "harvest/v1/r1/command",
                &vec![b' '; MAX_REQUEST_BYTES + 1],
                0
            ),
            Err(InboundRefusal::Oversized(_))
        ));
        let bad_requests: [&[u8]; 4] = [
            b"{",
            b"null",
            &request("fly"),
            br#"{"session":0,"client":"a","command":{"command":"stop"}}"#,
        ];
        for bad in bad_requests {
            assert!(matches!(
                gate.admit("harvest/v1/r1/command", bad, 0),
                Err(InboundRefusal::Malformed(_))
            ));
        }
        let counters = gate.counters();
        assert_eq!(
            (
                counters.admitted,
                counters.unknown_key,
                counters.oversized,
                counters.malformed
            ),
            (1, 2, 1, 4)
        );
    }

    #[test]
    fn bursts_are_limited_but_never_a_stop() {
        let mut gate = gate();
        let passed = (0..100)
            .filter(|_| {
                gate.admit("harvest/v1/r1/command", &request("heartbeat"), 0)
                    .is_ok()
            })
            .count();
        assert_eq!(passed as u32, BURST);
        assert_eq!(gate.counters().rate_limited, 100 - u64::from(BURST));
        let stop = gate
            .admit("harvest/v1/r1/command", &request("estop"), 0)
            .expect("a stop is never rate limited");
        assert_eq!(stop.command, Command::EmergencyStop);
        let payloads: [&[u8]; 3] = [b"", b"garbage", &vec![0u8; 10_000]];
        for payload in payloads {
            let stop = gate.admit("harvest/v1/r1/estop", payload, 0).expect("stop");
            assert_eq!(stop.command, Command::EmergencyStop);
            assert!(stop.token.is_empty());
        }
        assert_eq!(gate.counters().estop_bad_payload, 2);
        // A second later the lane is open again.
        assert!(
            gate.admit(
                "harvest/v1/r1/command",
                &request("heartbeat"),
                1_000_000_000
            )
            .is_ok()
        );
    }
}
