//! The recording's events channel: what triggered a flight-recorder clip (a failed attempt, a
//! safety violation, the e-stop engaged) and the operators' marks, as JSON messages with a JSON
//! schema, so Foxglove lists them (a Raw Messages or Log panel, the timeline) and a user jumps
//! to them. The recorder writes the channel into the continuous record and into every clip;
//! `rec info` counts it.
//!
//! Triggers are found in the recorded channels themselves ([`TriggerDetector`]): each event's
//! stamp is the triggering message's stack-clock stamp.

use crate::segment_writer::ForeignChannel;
use harvest_ipc::Payload;
use harvest_ipc::catalogue::{EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_MARK, SAFETY_VIOLATION};
use harvest_ipc::payloads::{
    EmergencyStop, HarvestEvent, HarvestEventKind, OperatorMark, SafetyViolation,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Topic of the events channel.
pub const EVENTS_TOPIC: &str = "recorder/events";
/// Schema name of the events channel.
pub const EVENT_SCHEMA_NAME: &str = "harvest.RecordedEvent";

/// What happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TriggerKind {
    /// An attempt ended without its apple (`harvest/events`).
    FailedAttempt,
    /// The safety monitor found a rule broken (`safety/violation`).
    SafetyViolation,
    /// The emergency stop was engaged (`safety/emergency_stop`, released to engaged).
    EmergencyStop,
    /// An operator's mark (`operator/mark`).
    Mark,
}

impl TriggerKind {
    pub const ALL: [Self; 4] = [
        Self::FailedAttempt,
        Self::SafetyViolation,
        Self::EmergencyStop,
        Self::Mark,
    ];

    /// The name in file names, JSON and listings.
    pub fn name(self) -> &'static str {
        match self {
            Self::FailedAttempt => "failed_attempt",
            Self::SafetyViolation => "safety_violation",
            Self::EmergencyStop => "emergency_stop",
            Self::Mark => "mark",
        }
    }

    pub fn parse(text: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.name() == text)
    }
}

/// One event as the events channel carries it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RecordedEvent {
    pub kind: TriggerKind,
    /// The triggering message's stamp on the stack clock (its `capture_ns`), ns.
    pub stamp_ns: u64,
    /// The same instant, UTC (ISO 8601), when the recording's clock is known.
    pub utc: String,
    /// The channel it was found on.
    pub topic: String,
    /// In words: the mark's text, the violation's description, the attempt's cause.
    pub text: String,
    /// The clip file that holds it (file name), when a flight recorder wrote one.
    pub clip: String,
}

impl RecordedEvent {
    pub fn to_json(&self) -> Vec<u8> {
        // A struct of strings and integers always serializes.
        serde_json::to_vec(self).unwrap_or_default()
    }

    pub fn from_json(bytes: &[u8]) -> Option<Self> {
        serde_json::from_slice(bytes).ok()
    }
}

/// The JSON Schema of [`RecordedEvent`].
pub fn event_schema() -> serde_json::Value {
    let kinds: Vec<&str> = TriggerKind::ALL.iter().map(|kind| kind.name()).collect();
    serde_json::json!({
        "title": EVENT_SCHEMA_NAME,
        "type": "object",
        "properties": {
            "kind": { "type": "string", "enum": kinds },
            "stamp_ns": { "type": "integer", "description": "stack clock (CLOCK_MONOTONIC) ns" },
            "utc": { "type": "string" },
            "topic": { "type": "string" },
            "text": { "type": "string" },
            "clip": { "type": "string" }
        },
        "required": ["kind", "stamp_ns", "topic", "text"]
    })
}

/// The events channel of a recording.
pub fn events_channel() -> ForeignChannel {
    ForeignChannel {
        topic: EVENTS_TOPIC.to_owned(),
        schema_name: EVENT_SCHEMA_NAME.to_owned(),
        schema_encoding: "jsonschema".to_owned(),
        schema_data: event_schema().to_string().into_bytes(),
        message_encoding: "json".to_owned(),
        metadata: BTreeMap::from([(
            "description".to_owned(),
            "flight-recorder triggers and operator marks".to_owned(),
        )]),
    }
}

/// Finds triggers in recorded messages (encoded catalogue payloads).
#[derive(Debug, Default)]
pub struct TriggerDetector {
    /// The e-stop's last state, so only the engaging edge triggers.
    estop_engaged: bool,
    /// The last violation seen, so a repeated stop request counts once.
    last_violation: Option<SafetyViolation>,
}

impl TriggerDetector {
    /// The trigger `data` (a message of `topic`) is, if any. `utc` turns a stack stamp into UTC.
    pub fn detect(
        &mut self,
        topic: &str,
        data: &[u8],
        utc: impl Fn(u64) -> String,
    ) -> Option<RecordedEvent> {
        let event = |kind, stamp_ns: u64, text: String| RecordedEvent {
            kind,
            stamp_ns,
            utc: utc(stamp_ns),
            topic: topic.to_owned(),
            text,
            clip: String::new(),
        };
        if topic == HARVEST_EVENTS.spec.topic {
            let harvest = decode::<HarvestEvent>(data)?;
            let kind = harvest.kind.get().ok()?;
            let failed = match kind {
                HarvestEventKind::AttemptEnded => harvest.harvested == 0,
                HarvestEventKind::DispatchTimedOut => true,
                _ => false,
            };
            if !failed {
                return None;
            }
            let cause = harvest
                .cause
                .get()
                .map(|cause| cause.label())
                .unwrap_or("unknown");
            let text = format!(
                "arm {} apple {}: {cause} {}",
                harvest.arm_id,
                harvest.apple_id,
                harvest.reason.as_str()
            );
            return Some(event(
                TriggerKind::FailedAttempt,
                harvest.header.capture_ns,
                text.trim_end().to_owned(),
            ));
        }
        if topic == SAFETY_VIOLATION.spec.topic {
            let violation = decode::<SafetyViolation>(data)?;
            if self
                .last_violation
                .is_some_and(|last| last.same_finding(&violation))
            {
                return None;
            }
            self.last_violation = Some(violation);
            return Some(event(
                TriggerKind::SafetyViolation,
                violation.header.capture_ns,
                violation.description.as_str().to_owned(),
            ));
        }
        if topic == EMERGENCY_STOP.spec.topic {
            let stop = decode::<EmergencyStop>(data)?;
            let engaged = stop.engaged != 0;
            let was_engaged = std::mem::replace(&mut self.estop_engaged, engaged);
            if !engaged || was_engaged {
                return None;
            }
            return Some(event(
                TriggerKind::EmergencyStop,
                stop.header.capture_ns,
                stop.reason.as_str().to_owned(),
            ));
        }
        if topic == OPERATOR_MARK.spec.topic {
            let mark = decode::<OperatorMark>(data)?;
            return Some(event(
                TriggerKind::Mark,
                mark.header.capture_ns,
                format!("{} ({})", mark.text.as_str(), mark.source.as_str()),
            ));
        }
        None
    }
}

fn decode<T: Payload + Default>(data: &[u8]) -> Option<T> {
    let mut value = T::default();
    T::decode_into(data, &mut value).ok()?;
    Some(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::payloads::{HarvestCause, HarvestEventSource};

    fn encoded<T: Payload>(value: &T) -> Vec<u8> {
        let mut bytes = Vec::new();
        value.encode(&mut bytes).expect("encode");
        bytes
    }

    fn utc(stamp_ns: u64) -> String {
        format!("t{stamp_ns}")
    }

    #[test]
    fn finds_failed_attempts_violations_the_engaging_edge_and_marks() {
        let mut detector = TriggerDetector::default();
        let mut ended = HarvestEvent::new(
            7,
            HarvestEventSource::Arm1,
            HarvestEventKind::AttemptEnded,
            1,
            42,
        );
        ended.harvested = 1;
        assert_eq!(
            detector.detect("harvest/events", &encoded(&ended), utc),
            None
        );
        ended.harvested = 0;
        ended.cause.set(HarvestCause::AppleLost);
        let failed = detector
            .detect("harvest/events", &encoded(&ended), utc)
            .expect("a failed attempt");
        assert_eq!(failed.kind, TriggerKind::FailedAttempt);
        assert_eq!(failed.stamp_ns, 7);
        assert_eq!(failed.utc, "t7");
        assert!(failed.text.contains("apple_lost"), "{}", failed.text);

        let mut stop = EmergencyStop::default();
        stop.header.capture_ns = 9;
        assert_eq!(
            detector.detect("safety/emergency_stop", &encoded(&stop), utc),
            None
        );
        stop.engaged = 1;
        let engaged = detector
            .detect("safety/emergency_stop", &encoded(&stop), utc)
            .expect("the engaging edge");
        assert_eq!(engaged.kind, TriggerKind::EmergencyStop);
        // Latched state repeated: no new trigger.
        assert_eq!(
            detector.detect("safety/emergency_stop", &encoded(&stop), utc),
            None
        );

        let violation = SafetyViolation {
            violated_ns: 3,
            ..SafetyViolation::default()
        };
        let found = detector.detect("safety/violation", &encoded(&violation), utc);
        assert_eq!(found.map(|e| e.kind), Some(TriggerKind::SafetyViolation));
        assert_eq!(
            detector.detect("safety/violation", &encoded(&violation), utc),
            None,
            "a repeated request is the same finding"
        );

        let mark = OperatorMark {
            text: harvest_ipc::FixedString::new("bruised apple"),
            source: harvest_ipc::FixedString::new("ctl ana"),
            ..OperatorMark::default()
        };
        let marked = detector
            .detect("operator/mark", &encoded(&mark), utc)
            .expect("a mark");
        assert_eq!(marked.text, "bruised apple (ctl ana)");
        let json = marked.to_json();
        assert_eq!(RecordedEvent::from_json(&json), Some(marked));
        assert_eq!(detector.detect("arm1/state", &[], utc), None);
    }

    #[test]
    fn the_channel_is_json_with_a_json_schema() {
        let channel = events_channel();
        assert_eq!(channel.message_encoding, "json");
        assert_eq!(channel.schema_encoding, "jsonschema");
        let schema: serde_json::Value =
            serde_json::from_slice(&channel.schema_data).expect("schema is JSON");
        assert_eq!(schema["properties"]["kind"]["enum"][3], "mark");
        assert_eq!(
            TriggerKind::parse("emergency_stop"),
            Some(TriggerKind::EmergencyStop)
        );
    }
}
