//! `harvest/events` and `safety/emergency_stop` -> `/events` log lines.
//!
//! Level: error for an engaged emergency stop; warning for refusals, time-outs and attempts
//! that did not harvest; info otherwise. `name` is the reporting process (`arm1`, `arm2`,
//! `vacuum`, `safety`).

use crate::stamps::TimeBase;
use foxglove::messages::{Log, log};
use harvest_ipc::payloads::{
    EmergencyStop, HarvestCause, HarvestEvent, HarvestEventKind, HarvestEventSource,
};

/// How severe an event is for the log.
pub fn level(event: &HarvestEvent) -> log::Level {
    match event.kind.get().ok() {
        Some(HarvestEventKind::EmergencyStop) if event.harvested != 0 => log::Level::Error,
        Some(
            HarvestEventKind::TargetRejected
            | HarvestEventKind::ValveRefused
            | HarvestEventKind::DispatchTimedOut,
        ) => log::Level::Warning,
        Some(HarvestEventKind::AttemptEnded | HarvestEventKind::AttemptFinished)
            if event.harvested == 0 =>
        {
            log::Level::Warning
        }
        Some(_) => log::Level::Info,
        None => log::Level::Unknown,
    }
}

/// One line of text for an event: `apple 7 arm 1: TargetRejected (outside_workspace) - reason`.
pub fn event_text(event: &HarvestEvent) -> String {
    let kind = event.kind.get().ok().map_or_else(
        || format!("kind {}", event.kind.raw()),
        |kind| format!("{kind:?}"),
    );
    let mut text = String::new();
    if event.apple_id != 0 {
        text.push_str(&format!("apple {} ", event.apple_id));
    }
    if event.arm_id != 0 {
        text.push_str(&format!("arm {} ", event.arm_id));
    }
    text.push_str(&kind);
    match event.cause.get().ok() {
        Some(HarvestCause::None) => {}
        Some(cause) => text.push_str(&format!(" ({})", cause.label())),
        None => text.push_str(&format!(" (cause {})", event.cause.raw())),
    }
    if matches!(
        event.kind.get().ok(),
        Some(HarvestEventKind::AttemptEnded | HarvestEventKind::AttemptFinished)
    ) {
        text.push_str(if event.harvested != 0 {
            ": harvested"
        } else {
            ": not harvested"
        });
    }
    if event.kind.get().ok() == Some(HarvestEventKind::PhaseChanged)
        && let Some(phase) = event.phase.get().ok()
    {
        text.push_str(&format!(" to {phase:?}"));
    }
    let reason = event.reason.as_str();
    if !reason.is_empty() {
        text.push_str(" - ");
        text.push_str(reason);
    }
    text
}

/// The log line of a harvest event.
pub fn event_log(event: &HarvestEvent, time: &TimeBase) -> Log {
    Log {
        timestamp: Some(time.timestamp(event.header.capture_ns)),
        level: level(event) as i32,
        message: event_text(event),
        name: event
            .source
            .get()
            .map_or("unknown", HarvestEventSource::name)
            .to_owned(),
        file: String::new(),
        line: 0,
    }
}

/// The log line of an emergency-stop message.
pub fn emergency_stop_log(stop: &EmergencyStop, time: &TimeBase) -> Log {
    let (level, state) = if stop.engaged != 0 {
        (log::Level::Error, "engaged")
    } else {
        (log::Level::Info, "released")
    };
    Log {
        timestamp: Some(time.timestamp(stop.header.capture_ns)),
        level: level as i32,
        message: format!("emergency stop {state}: {}", stop.reason.as_str()),
        name: "safety".to_owned(),
        file: String::new(),
        line: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_ipc::FixedString;

    #[test]
    fn events_read_as_lines_with_levels() {
        let mut event = HarvestEvent::new(
            3_000_000_000,
            HarvestEventSource::Arm1,
            HarvestEventKind::TargetRejected,
            1,
            7,
        );
        event.cause = HarvestCause::OutsideWorkspace.into();
        event.reason = FixedString::new("joint theta would be 0.7");
        let line = event_log(&event, &TimeBase::MONOTONIC);
        assert_eq!(
            line.message,
            "apple 7 arm 1 TargetRejected (outside_workspace) - joint theta would be 0.7"
        );
        assert_eq!(line.level, log::Level::Warning as i32);
        assert_eq!(line.name, "arm1");
        let mut ended = HarvestEvent::new(
            0,
            HarvestEventSource::Arm2,
            HarvestEventKind::AttemptEnded,
            2,
            9,
        );
        ended.harvested = 1;
        assert_eq!(event_text(&ended), "apple 9 arm 2 AttemptEnded: harvested");
        assert_eq!(level(&ended), log::Level::Info);
        let stop = EmergencyStop {
            engaged: 1,
            reason: FixedString::new("operator"),
            ..EmergencyStop::default()
        };
        let line = emergency_stop_log(&stop, &TimeBase::MONOTONIC);
        assert_eq!(line.level, log::Level::Error as i32);
        assert_eq!(line.message, "emergency stop engaged: operator");
    }
}
