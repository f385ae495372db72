//! The JSON the station reads: each stack payload's own JSON view ([`Payload::to_json`], the
//! one `harvest rec cat` prints), header stamps included, so an independent client decodes it
//! with any JSON library. And what counts as a change for the on-change channels (the mode is
//! republished at 10 Hz, each time with a new header: only its content counts). And the
//! e-stop as the mode reports it, for as long as no stop message was heard.

use harvest_ipc::payloads::{EmergencyStop, OperatorModeState, ProcessHealth};
use harvest_ipc::{FixedString, Payload};

/// The JSON bytes of one message.
pub fn json_bytes<T: Payload>(message: &T) -> Vec<u8> {
    serde_json::to_vec(&message.to_json()).unwrap_or_default()
}

/// What a change of the operator's mode is.
pub type ModeContent = (u8, u8, [u8; 2], u8, u64, u64, u8);

pub fn mode_content(mode: &OperatorModeState) -> ModeContent {
    (
        mode.mode,
        mode.emergency_stop_engaged,
        mode.arms_enabled,
        mode.field_hold,
        mode.controlling_session,
        mode.last_change_ns,
        mode.platform_in_motion,
    )
}

/// What a change of the emergency stop is.
pub fn estop_content(stop: &EmergencyStop) -> (u8, String) {
    (stop.engaged, stop.reason.as_str().to_owned())
}

/// The e-stop's state as the executive's mode carries it. The executive, the one writer of
/// both channels, sends a stop message only when it engages or releases the stop (nothing at
/// a start where the stop is not engaged), and a late subscriber of a stop sent once may not
/// get it, while the mode comes again at 10 Hz with `emergency_stop_engaged`. So until a stop
/// message is heard the link sends this one, and a station always learns the robot's stop.
/// The header is the mode's with `msg_seq` 0 (no message of `safety/emergency_stop`); the
/// reason is the mode's last change while engaged, `not engaged` otherwise.
pub fn estop_from_mode(mode: &OperatorModeState) -> EmergencyStop {
    let engaged = mode.emergency_stop_engaged != 0;
    let mut header = mode.header;
    header.msg_seq = 0;
    EmergencyStop {
        header,
        engaged: u8::from(engaged),
        reason: FixedString::new(if engaged {
            mode.last_change_reason.as_str()
        } else {
            "not engaged"
        }),
        ..EmergencyStop::default()
    }
}

/// What a change of one process's heartbeat is (its counters are not).
pub type HealthContent = (String, u32, u8, u8);

pub fn health_content(health: &ProcessHealth) -> HealthContent {
    (
        health.process_name.as_str().to_owned(),
        health.pid,
        health.run_state.raw(),
        health.last_device_error.raw(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_json_carries_the_stamps_and_changes_ignore_the_header() {
        let mut mode = OperatorModeState::default();
        mode.header.capture_ns = 42;
        let value: serde_json::Value = serde_json::from_slice(&json_bytes(&mode)).expect("json");
        assert_eq!(value["header"]["capture_ns"], 42);
        let mut later = mode;
        later.header.msg_seq += 1;
        assert_eq!(mode_content(&mode), mode_content(&later));
        later.emergency_stop_engaged = 1;
        assert_ne!(mode_content(&mode), mode_content(&later));
    }

    #[test]
    fn the_stop_from_the_mode_says_whether_it_is_engaged_and_why() {
        let mut mode = OperatorModeState::default();
        mode.header.msg_seq = 12;
        mode.header.capture_ns = 7;
        let released = estop_from_mode(&mode);
        assert_eq!(estop_content(&released), (0, "not engaged".to_owned()));
        assert_eq!(released.header.msg_seq, 0);
        assert_eq!(released.header.capture_ns, 7);
        mode.emergency_stop_engaged = 1;
        mode.last_change_reason = FixedString::new("emergency stop by ctl ana");
        let engaged = estop_from_mode(&mode);
        assert_eq!(
            estop_content(&engaged),
            (1, "emergency stop by ctl ana".to_owned())
        );
        let value: serde_json::Value = serde_json::from_slice(&json_bytes(&engaged)).expect("json");
        assert_eq!(value["engaged"], 1);
    }
}
