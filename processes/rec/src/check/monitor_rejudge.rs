//! The safety monitor re-judged: this build's monitor rules, run on the recording's monitored
//! channels (`harvest monitor --recording`, given by the caller as the messages it would have
//! published), compared with the `safety/violation` messages the live monitor published (read
//! in the control nodes' pass, [`crate::check::control_rerun::read_recording`]). The
//! live monitor repeats an unanswered stop request every 100 ms of its own clock, so copies of
//! one finding (same rule, arm and violation time) count once on both sides.

use harvest_ipc::Payload;
use harvest_ipc::catalogue::SAFETY_VIOLATION;
use harvest_ipc::payloads::SafetyViolation;

use crate::check::report::ChannelCheck;

/// Set by the publisher, not by the rules: never compared.
const STAMPS: [&str; 3] = ["header.msg_seq", "header.capture_ns", "header.publish_ns"];

/// Keeps the first copy of each finding (same rule, arm and violation time).
fn findings(
    messages: impl IntoIterator<Item = (u64, SafetyViolation)>,
) -> Vec<(u64, SafetyViolation)> {
    let mut kept: Vec<(u64, SafetyViolation)> = Vec::new();
    for (at, message) in messages {
        if !kept.iter().any(|(_, seen)| seen.same_finding(&message)) {
            kept.push((at, message));
        }
    }
    kept
}

/// Compares `rejudged` (the re-run monitor's messages, in order) with `recorded` (the
/// recording's `safety/violation` messages with their log times; `start_ns`: the recording's
/// first log time).
pub fn check_violations(
    recorded: &[(u64, SafetyViolation)],
    start_ns: u64,
    rejudged: &[SafetyViolation],
    tolerance: Option<f64>,
) -> ChannelCheck {
    let topic = SAFETY_VIOLATION.spec.topic;
    let recorded = findings(recorded.iter().copied());
    let rejudged = findings(rejudged.iter().map(|message| (0, *message)));
    let mut check = ChannelCheck::new(topic);
    for index in 0..recorded.len().max(rejudged.len()) {
        check.compare_message(
            recorded
                .get(index)
                .map(|(at_ns, old)| (*at_ns, old.to_json())),
            rejudged.get(index).map(|(_, new)| new.to_json()),
            &STAMPS,
            tolerance,
            start_ns,
            start_ns,
        );
    }
    if recorded.len() != rejudged.len() {
        check.count_mismatch = Some((recorded.len() as u64, rejudged.len() as u64));
    }
    check
}
