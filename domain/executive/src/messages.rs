//! The executive's messages, built from its decisions: the emergency stop, manual orders,
//! acknowledgements and the mode.

use harvest_ipc::payloads::{
    ArmManualCommand, ArmManualKind, EmergencyStop, OperatorAck, OperatorCommand, OperatorModeCode,
    OperatorModeState,
};
use harvest_ipc::{FixedString, Header};
use harvest_operator::{Action, Decision, Executive, PlatformView};

fn header(now_ns: u64) -> Header {
    Header {
        capture_ns: now_ns,
        ..Header::default()
    }
}

/// `safety/emergency_stop`, engaged or released, with the reason.
pub fn emergency_stop(now_ns: u64, engaged: bool, reason: &str) -> EmergencyStop {
    if engaged {
        tracing::warn!(%reason, "emergency stop engaged");
    } else {
        tracing::info!(%reason, "emergency stop released");
    }
    EmergencyStop {
        header: header(now_ns),
        engaged: u8::from(engaged),
        _reserved: [0; 7],
        reason: FixedString::new(reason),
    }
}

/// The `armN/manual` order of a manual action (`None` for any other action).
pub fn manual_order(now_ns: u64, action: &Action) -> Option<ArmManualCommand> {
    let (request_id, arm_id, kind, goal, speed_fraction) = match *action {
        Action::ArmMoveTo {
            arm,
            goal,
            speed_fraction,
            request_id,
        } => (request_id, arm, ArmManualKind::MoveTo, goal, speed_fraction),
        Action::ArmStop { arm } => (0, arm, ArmManualKind::Stop, [f64::NAN; 4], 0.0),
        _ => return None,
    };
    Some(ArmManualCommand {
        header: header(now_ns),
        request_id,
        arm_id,
        kind: kind as u8,
        _reserved: [0; 6],
        goal_joint_position: goal,
        speed_fraction,
    })
}

/// The answer to `command` on `operator/ack`; `mode` is the mode after it.
pub fn ack(
    now_ns: u64,
    command: &OperatorCommand,
    decision: &Decision,
    mode: OperatorModeCode,
) -> OperatorAck {
    OperatorAck {
        header: header(now_ns),
        request_id: command.request_id,
        session_id: command.session_id,
        code: command.code,
        accepted: u8::from(decision.is_accepted()),
        refusal: decision.refusal.as_ref().map_or(0, |r| r.code() as u8),
        mode: mode as u8,
        _reserved: [0; 3],
        motion_duration_ms: decision.motion_duration_ms,
        _reserved2: [0; 4],
        reason: FixedString::new(&decision.reason),
    }
}

/// `operator/mode`: the executive's state, the platform and the row's hold.
pub fn mode_state(
    now_ns: u64,
    executive: &Executive,
    platform_present: bool,
    field_hold: bool,
    platform: Option<&PlatformView>,
) -> OperatorModeState {
    let mut state = OperatorModeState {
        header: header(now_ns),
        ..OperatorModeState::default()
    };
    executive.fill_state(&mut state);
    state.platform_present = u8::from(platform_present);
    state.field_hold = u8::from(field_hold);
    match platform {
        Some(p) => {
            state.platform_in_motion = u8::from(p.in_motion);
            state.platform_position_m = p.position_m;
        }
        None => {
            state.platform_in_motion = 0;
            state.platform_position_m = [f64::NAN; 2];
        }
    }
    state
}
