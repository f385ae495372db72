use super::*;
use crate::command::JointName;
use crate::stack_view::PlatformView;
use harvest_ipc::payloads::{ArmPhase, OperatorRefusalCode};
use harvest_robot_model::params::ArmParams;

const MS: u64 = 1_000_000;

struct Bench {
    executive: Executive,
    token: ControlToken,
    now_ns: u64,
    view: StackView,
    request_id: u64,
}

fn arm_view(home: [f64; 4]) -> ArmView {
    ArmView {
        joint_position: home,
        joint_velocity: [0.0; 4],
        phase: Some(ArmPhase::Idle),
        age_ns: 5 * MS,
    }
}

impl Bench {
    fn new(initial_mode: OperatorModeCode) -> Self {
        let token = ControlToken::generate().expect("token");
        let config = ExecutiveConfig {
            initial_mode,
            ..ExecutiveConfig::default()
        };
        Self {
            executive: Executive::new(config, token.clone(), 1_000 * MS, false, None),
            token,
            now_ns: 1_000 * MS,
            view: StackView {
                arms: [
                    Some(arm_view(ArmParams::arm1().home.to_array())),
                    Some(arm_view(ArmParams::arm2().home.to_array())),
                ],
                platform: Some(PlatformView {
                    position_m: [0.0, 0.0],
                    in_motion: false,
                    travel_max_m: [0.5, 0.8],
                }),
            },
            request_id: 0,
        }
    }

    fn send_as(&mut self, session: u64, token: &str, command: Command) -> Decision {
        self.request_id += 1;
        let message = command.to_message(self.request_id, session, token, "test");
        self.executive.handle(self.now_ns, &message, &self.view)
    }

    fn send(&mut self, command: Command) -> Decision {
        let token = self.token.as_str().to_owned();
        self.send_as(1, &token, command)
    }

    fn advance(&mut self, ms: u64) -> Vec<Action> {
        self.now_ns += ms * MS;
        self.executive.tick(self.now_ns, &self.view)
    }
}

fn refusal_code(decision: &Decision) -> Option<OperatorRefusalCode> {
    decision.refusal.as_ref().map(Refusal::code)
}

#[test]
fn the_harvest_starts_pauses_resumes_and_stops() {
    let mut b = Bench::new(OperatorModeCode::Idle);
    assert_eq!(b.executive.mode(), OperatorModeCode::Idle);
    assert!(b.send(Command::Start).is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    assert!(b.send(Command::Pause).is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::Paused);
    assert!(b.send(Command::Resume).is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    assert!(b.send(Command::Stop).is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::Idle);
    let mut state = OperatorModeState::default();
    b.executive.fill_state(&mut state);
    assert_eq!(state.mode_code(), Some(OperatorModeCode::Idle));
    assert_eq!(state.controlling_session, 1);
    assert_eq!(state.controller.as_str(), "test");
    assert!(state.last_change_reason.as_str().contains("stopped"));
}

#[test]
fn an_unknown_command_is_refused_and_changes_nothing() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    let mut message = Command::Stop.to_message(1, 1, b.token.as_str(), "test");
    message.code = 200;
    let decision = b.executive.handle(b.now_ns, &message, &b.view);
    assert_eq!(
        refusal_code(&decision),
        Some(OperatorRefusalCode::UnknownCommand)
    );
    assert!(decision.actions.is_empty());
    assert!(decision.reason.contains("200"), "{}", decision.reason);
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    assert!(b.executive.controller().is_none());
}

#[test]
fn a_missing_or_wrong_token_is_refused_for_every_command_but_the_emergency_stop() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    let missing = b.send_as(1, "", Command::Pause);
    assert_eq!(
        refusal_code(&missing),
        Some(OperatorRefusalCode::MissingToken)
    );
    let wrong = ControlToken::generate().expect("token");
    for command in [
        Command::Pause,
        Command::Heartbeat,
        Command::Release,
        Command::Start,
    ] {
        let decision = b.send_as(1, wrong.as_str(), command);
        assert_eq!(
            refusal_code(&decision),
            Some(OperatorRefusalCode::WrongToken)
        );
        assert!(decision.actions.is_empty());
    }
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    assert!(b.executive.controller().is_none());

    // The stop needs no authority: a wrong token stops the robot, takes no control, and the
    // reason says the token was not shown.
    let estop = b.send_as(7, wrong.as_str(), Command::EmergencyStop);
    assert!(estop.is_accepted(), "{}", estop.reason);
    assert!(matches!(
        estop.actions.first(),
        Some(Action::EngageEmergencyStop { reason }) if reason.contains("without the control token")
    ));
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
    assert!(b.executive.controller().is_none());
    // The release still needs the token; refused, the stop stays engaged.
    for token in ["", wrong.as_str()] {
        let release = b.send_as(7, token, Command::Release);
        assert!(!release.is_accepted());
        assert!(release.actions.is_empty());
    }
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
    // With the token the release returns to idle, never to harvesting.
    assert!(b.send(Command::Release).is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::Idle);

    // No token at all and no session (session id 0): stopped all the same.
    let estop = b.send_as(0, "", Command::EmergencyStop);
    assert!(estop.is_accepted(), "{}", estop.reason);
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
}

#[test]
fn the_emergency_stop_is_taken_without_token_while_another_session_controls() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    assert!(b.send(Command::Heartbeat).is_accepted());
    b.now_ns += 100 * MS;
    let estop = b.send_as(2, "", Command::EmergencyStop);
    assert!(estop.is_accepted(), "{}", estop.reason);
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
    // The controlling session keeps control; the stopping one gained none.
    assert_eq!(b.executive.controller().map(|c| c.session_id), Some(1));
}

#[test]
fn a_second_session_is_refused_while_the_first_is_heard() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    let token = b.token.as_str().to_owned();
    assert!(b.send_as(1, &token, Command::Heartbeat).is_accepted());
    b.now_ns += 200 * MS;
    let second = b.send_as(2, &token, Command::Pause);
    assert_eq!(
        refusal_code(&second),
        Some(OperatorRefusalCode::OtherSessionInControl)
    );
    assert!(
        second.reason.contains("test is in control"),
        "{}",
        second.reason
    );
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    // The emergency stop is taken from any session.
    let estop = b.send_as(2, &token, Command::EmergencyStop);
    assert!(estop.is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
    // Release is not: it is a control command.
    let release = b.send_as(2, &token, Command::Release);
    assert_eq!(
        refusal_code(&release),
        Some(OperatorRefusalCode::OtherSessionInControl)
    );
    // Once the first session leaves (or is silent), the second one controls.
    assert!(b.send_as(1, &token, Command::LeaveControl).is_accepted());
    assert!(b.send_as(2, &token, Command::Release).is_accepted());
    assert_eq!(b.executive.controller().map(|c| c.session_id), Some(2));
    b.advance(600);
    assert!(b.executive.controller().is_none());
    assert!(b.send_as(3, &token, Command::Start).is_accepted());
}

#[test]
fn commands_the_mode_forbids_are_refused_with_a_hint() {
    let mut b = Bench::new(OperatorModeCode::Idle);
    for (command, hint) in [
        (Command::Pause, "use start"),
        (Command::Resume, "use start"),
        (Command::Release, "not engaged"),
    ] {
        let decision = b.send(command);
        assert_eq!(
            refusal_code(&decision),
            Some(OperatorRefusalCode::ForbiddenByMode)
        );
        assert!(decision.reason.contains(hint), "{}", decision.reason);
    }
    assert!(b.send(Command::Start).is_accepted());
    for command in [
        Command::Start,
        Command::Resume,
        Command::Home,
        Command::DropOff { arm: 1 },
        Command::Jog {
            arm: 1,
            joint: JointName::Theta,
            delta: 0.05,
        },
        Command::PlatformMove {
            target_m: [0.1, 0.1],
        },
    ] {
        let decision = b.send(command);
        assert_eq!(
            refusal_code(&decision),
            Some(OperatorRefusalCode::ForbiddenByMode),
            "{command:?}"
        );
        assert!(decision.actions.is_empty());
    }
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    // While the emergency stop is engaged nothing but release (and estop) is accepted.
    let estop = b.send(Command::EmergencyStop);
    assert!(matches!(
        estop.actions.first(),
        Some(Action::EngageEmergencyStop { .. })
    ));
    for command in [
        Command::Start,
        Command::Resume,
        Command::Stop,
        Command::Home,
        Command::Jog {
            arm: 2,
            joint: JointName::D,
            delta: 0.01,
        },
    ] {
        let decision = b.send(command);
        assert_eq!(
            refusal_code(&decision),
            Some(OperatorRefusalCode::ForbiddenByMode),
            "{command:?}"
        );
        assert!(decision.reason.contains("release the emergency stop"));
    }
    assert!(b.send(Command::EmergencyStop).is_accepted());
    let release = b.send(Command::Release);
    assert_eq!(release.actions, vec![Action::ReleaseEmergencyStop]);
    // Never back to harvesting by itself.
    assert_eq!(b.executive.mode(), OperatorModeCode::Idle);
}

#[test]
fn a_jog_outside_the_joint_limits_or_too_large_is_refused() {
    let mut b = Bench::new(OperatorModeCode::Idle);
    let limits = ArmParams::arm1().position_limits;
    // theta at 0: 0.35 rad would stay inside [-17, 30] deg up, and leave it down.
    let down = b.send(Command::Jog {
        arm: 1,
        joint: JointName::Theta,
        delta: -0.35,
    });
    assert_eq!(
        refusal_code(&down),
        Some(OperatorRefusalCode::OutsideLimits)
    );
    assert!(down.reason.contains("theta"), "{}", down.reason);
    assert!(limits.min.theta_rad > -0.35);
    let too_large = b.send(Command::Jog {
        arm: 1,
        joint: JointName::D,
        delta: 0.5,
    });
    assert_eq!(
        refusal_code(&too_large),
        Some(OperatorRefusalCode::BadArgument)
    );
    let below = b.send(Command::Jog {
        arm: 2,
        joint: JointName::D,
        delta: -0.05,
    });
    assert_eq!(
        refusal_code(&below),
        Some(OperatorRefusalCode::OutsideLimits)
    );
    assert_eq!(b.executive.mode(), OperatorModeCode::Idle);
    // Inside: accepted, forwarded to the arm with the planned duration.
    let ok = b.send(Command::Jog {
        arm: 1,
        joint: JointName::D,
        delta: 0.05,
    });
    assert!(ok.is_accepted(), "{}", ok.reason);
    assert!(ok.motion_duration_ms > 0);
    match ok.actions.as_slice() {
        [Action::ArmMoveTo { arm: 1, goal, .. }] => assert!((goal[0] - 0.05).abs() < 1e-12),
        other => panic!("unexpected actions {other:?}"),
    }
    assert_eq!(b.executive.mode(), OperatorModeCode::Manual);
}

#[test]
fn manual_moves_need_idle_arms_at_rest_with_a_fresh_state_and_the_clearance() {
    let mut b = Bench::new(OperatorModeCode::Paused);
    if let Some(view) = b.view.arms[0].as_mut() {
        view.phase = Some(ArmPhase::Retract);
    }
    let busy = b.send(Command::DropOff { arm: 1 });
    assert_eq!(refusal_code(&busy), Some(OperatorRefusalCode::ArmBusy));
    let platform = b.send(Command::PlatformMove {
        target_m: [0.1, 0.1],
    });
    assert_eq!(refusal_code(&platform), Some(OperatorRefusalCode::ArmBusy));
    if let Some(view) = b.view.arms[0].as_mut() {
        view.phase = Some(ArmPhase::Idle);
        view.age_ns = 2_000 * MS;
    }
    let stale = b.send(Command::Home);
    assert_eq!(
        refusal_code(&stale),
        Some(OperatorRefusalCode::ArmStateUnknown)
    );
    b.view.arms[0] = Some(arm_view(ArmParams::arm1().home.to_array()));
    // Both arms yawed toward each other (eq. 1: a positive phi of arm 1 and a negative phi of
    // arm 2 point the tubes toward the middle): extending arm 1 runs into arm 2.
    let mut near = ArmParams::arm1().home.to_array();
    near[2] = ArmParams::arm1().position_limits.max.phi_rad - 0.01;
    let mut other = ArmParams::arm2().home.to_array();
    other[2] = ArmParams::arm2().position_limits.min.phi_rad + 0.01;
    b.view.arms[0] = Some(arm_view(near));
    b.view.arms[1] = Some(arm_view(other));
    let clash = b.send(Command::Jog {
        arm: 1,
        joint: JointName::D,
        delta: 0.1,
    });
    assert_eq!(
        refusal_code(&clash),
        Some(OperatorRefusalCode::Clearance),
        "{}",
        clash.reason
    );
    assert_eq!(b.executive.mode(), OperatorModeCode::Paused);
    // Platform travel.
    b.view.arms[0] = Some(arm_view(ArmParams::arm1().home.to_array()));
    b.view.arms[1] = Some(arm_view(ArmParams::arm2().home.to_array()));
    let out = b.send(Command::PlatformMove {
        target_m: [0.6, 0.1],
    });
    assert_eq!(refusal_code(&out), Some(OperatorRefusalCode::OutsideLimits));
    assert!(out.reason.contains("in-out"));
    b.view.platform = None;
    let none = b.send(Command::PlatformMove {
        target_m: [0.1, 0.1],
    });
    assert_eq!(refusal_code(&none), Some(OperatorRefusalCode::Device));
    let home = b.send(Command::Home);
    assert!(home.is_accepted());
    assert_eq!(home.actions.len(), 2);
}

#[test]
fn a_silent_controller_stops_manual_motion_but_not_the_mode() {
    let mut b = Bench::new(OperatorModeCode::Idle);
    let jog = b.send(Command::Jog {
        arm: 2,
        joint: JointName::Theta,
        delta: 0.3,
    });
    assert!(jog.is_accepted(), "{}", jog.reason);
    // Heartbeats keep the motion going.
    for _ in 0..5 {
        assert!(b.advance(200).is_empty());
        assert!(b.send(Command::Heartbeat).is_accepted());
    }
    let actions = b.advance(501);
    assert_eq!(
        actions,
        vec![
            Action::ArmStop { arm: 1 },
            Action::ArmStop { arm: 2 },
            Action::PlatformStop
        ]
    );
    assert_eq!(b.executive.mode(), OperatorModeCode::Manual);
    assert!(b.executive.last_change().reason.contains("heartbeat"));
    assert!(b.advance(600).is_empty());
}

#[test]
fn harvesting_goes_on_without_any_session() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    assert!(b.send(Command::Pause).is_accepted());
    assert!(b.send(Command::Resume).is_accepted());
    assert!(b.advance(5_000).is_empty());
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
}

#[test]
fn a_restarted_executive_keeps_the_mode_and_the_engaged_stop() {
    let token = ControlToken::generate().expect("token");
    let mut previous = OperatorModeState {
        mode: OperatorModeCode::Paused as u8,
        arms_enabled: [1, 0],
        ..OperatorModeState::default()
    };
    let config = ExecutiveConfig::default();
    let restarted = Executive::new(config, token.clone(), 0, false, Some(&previous));
    assert_eq!(restarted.mode(), OperatorModeCode::Paused);
    assert_eq!(restarted.arms_enabled(), [true, false]);
    previous.mode = OperatorModeCode::Manual as u8;
    let from_manual = Executive::new(config, token.clone(), 0, false, Some(&previous));
    assert_eq!(from_manual.mode(), OperatorModeCode::Idle);
    let stopped = Executive::new(config, token, 0, true, Some(&previous));
    assert_eq!(stopped.mode(), OperatorModeCode::EmergencyStopped);
}

#[test]
fn disabling_an_arm_is_allowed_in_every_mode() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    assert!(
        b.send(Command::SetArmEnabled {
            arm: 2,
            enabled: false
        })
        .is_accepted()
    );
    assert_eq!(b.executive.arms_enabled(), [true, false]);
    assert!(b.send(Command::EmergencyStop).is_accepted());
    assert!(
        b.send(Command::SetArmEnabled {
            arm: 2,
            enabled: true
        })
        .is_accepted()
    );
    assert_eq!(b.executive.arms_enabled(), [true, true]);
}

#[test]
fn the_safety_monitor_engages_the_stop_once_and_only_an_operator_releases_it() {
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    let actions = b.executive.protective_stop(b.now_ns, "both valves open");
    assert!(matches!(
        actions.as_slice(),
        [Action::EngageEmergencyStop { reason }] if reason.contains("both valves open")
    ));
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
    assert!(b.executive.last_change().reason.contains("safety monitor"));
    // A burst of violations: the stop is published once.
    assert!(b.executive.protective_stop(b.now_ns, "again").is_empty());
    assert!(b.advance(1_000).is_empty());
    assert_eq!(b.executive.mode(), OperatorModeCode::EmergencyStopped);
    assert!(b.send(Command::Release).is_accepted());
    assert_eq!(b.executive.mode(), OperatorModeCode::Idle);
}

#[test]
fn next_stop_goes_to_the_row_only_with_a_row_and_while_harvesting() {
    // No row configured: refused whatever the mode, nothing to carry out.
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    let decision = b.send(Command::NextStop);
    assert_eq!(decision.refusal, Some(Refusal::NoRow));
    assert_eq!(refusal_code(&decision), Some(OperatorRefusalCode::Field));
    assert!(decision.actions.is_empty());
    assert!(
        decision.reason.contains("no row configured"),
        "{}",
        decision.reason
    );

    // With a row: routed to the stop cycle while harvesting.
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    b.executive.config.field_row = true;
    let mut decision = b.send(Command::NextStop);
    assert!(decision.is_accepted(), "{}", decision.reason);
    assert_eq!(decision.actions, vec![Action::NextStop]);
    assert_eq!(b.executive.mode(), OperatorModeCode::Harvesting);
    // The stop cycle's refusal becomes the acknowledgement's.
    decision.refuse(Refusal::NextStop(
        "an arm holds an apple: drop it off first".to_owned(),
    ));
    assert_eq!(refusal_code(&decision), Some(OperatorRefusalCode::Field));
    assert_eq!(
        decision.reason,
        "next stop refused: an arm holds an apple: drop it off first"
    );

    // Paused or e-stopped: the stop cycle does not run, the trailer must not drive.
    assert!(b.send(Command::Pause).is_accepted());
    let paused = b.send(Command::NextStop);
    assert_eq!(
        refusal_code(&paused),
        Some(OperatorRefusalCode::ForbiddenByMode)
    );
    assert!(paused.actions.is_empty());
    assert!(b.send(Command::EmergencyStop).is_accepted());
    let stopped = b.send(Command::NextStop);
    assert_eq!(
        refusal_code(&stopped),
        Some(OperatorRefusalCode::ForbiddenByMode)
    );
    assert!(
        stopped.reason.contains("release the emergency stop"),
        "{}",
        stopped.reason
    );

    // Another session's "next stop" is refused before it reaches the row.
    let mut b = Bench::new(OperatorModeCode::Harvesting);
    b.executive.config.field_row = true;
    assert!(b.send(Command::Heartbeat).is_accepted());
    let token = b.token.as_str().to_owned();
    let other = b.send_as(2, &token, Command::NextStop);
    assert_eq!(
        refusal_code(&other),
        Some(OperatorRefusalCode::OtherSessionInControl)
    );
    assert!(other.actions.is_empty());
}
