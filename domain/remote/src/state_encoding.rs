//! The JSON the station reads: each stack payload's own JSON view ([`Payload::to_json`], the
//! one `harvest rec cat` prints), header stamps included, so an independent client decodes it
//! with any JSON library. And what counts as a change for the on-change channels (the mode is
//! republished at 10 Hz, each time with a new header: only its content counts).

use harvest_ipc::Payload;
use harvest_ipc::payloads::{EmergencyStop, OperatorModeState, ProcessHealth};

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
}
