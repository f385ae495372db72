//! The one place that enforces the operator's mode ([`Executive`]).
//!
//! Modes ([`OperatorModeCode`]) and what moves in each:
//! - **idle**: nothing is assigned; arms hold where they are.
//! - **harvesting**: the vacuum supervisor dispatches apples to the enabled arms.
//! - **paused**: no new approach; an attempt under way runs to its end (approach, attach,
//!   retract, release), then the arm stays idle at the drop-off.
//! - **manual**: operator moves only (jog a joint, drop-off pose, home, platform); nothing is
//!   assigned.
//! - **estopped**: `safety/emergency_stop` is engaged: arms brake, valves close, nothing moves.
//!
//! Transitions: `start` (idle, paused, manual -> harvesting), `pause` (harvesting -> paused),
//! `resume` (paused -> harvesting), `stop` (harvesting, paused, manual -> idle), `estop` (any ->
//! estopped), `release` (estopped -> idle: never back to harvesting by itself), and a manual
//! move (`home`, `jog`, `drop-off`, `platform` from idle, paused or manual -> manual).
//! `next-stop` (harvesting, with a row configured) ends the row's current stop and advances;
//! the row's stop cycle may still refuse it (an arm holds an apple, something moves, the row is
//! done). `arm N enable|disable` is allowed in every mode (a disabled arm gets no new apple and
//! finishes the one it picks).
//!
//! Every command passes, in order: a known code; the control token; the single controlling
//! session (another live session is refused; a session is live while it was heard within the
//! heartbeat timeout); the mode; the arguments and the arms' states (idle, at rest, fresh);
//! the joint limits and the clearance between the arms. The emergency stop is the exception: it
//! needs no authority (ISO 13850: a stop is always allowed and takes effect at once), so a known
//! `estop` code is accepted from any session, with the token, a wrong one or none, even while
//! another session controls; it takes no control and only engages (the release is a control
//! command like the others and returns to idle). The safety monitor's protective stop
//! ([`Executive::protective_stop`]) likewise needs neither token nor session. In
//! manual mode, a motion under way is stopped when the controlling session is not heard for the heartbeat timeout (500 ms
//! by default). Refused commands change nothing.

use harvest_arm::manual_motion::MANUAL_SPEED_FRACTION;
use harvest_arm::node::ArmNodeConfig;
use harvest_ipc::FixedString;
use harvest_ipc::payloads::{OperatorCommand, OperatorModeCode, OperatorModeState};
use tracing::{info, warn};

use crate::action::Action;
use crate::command::{Command, JointName};
use crate::motion_check::{self, MotionLimits};
use crate::refusal::Refusal;
use crate::stack_view::{ArmView, StackView};
use crate::token::ControlToken;

/// Settings of the executive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExecutiveConfig {
    /// A controlling session silent this long loses control, and a manual motion under way is
    /// stopped, ns (default 500 ms).
    pub heartbeat_timeout_ns: u64,
    /// Checks of manual moves.
    pub limits: MotionLimits,
    /// Mode at start when no earlier mode is known (default idle; the simulated robot's launch
    /// profile starts harvesting).
    pub initial_mode: OperatorModeCode,
    /// The executive works a row (`--row-stops`): "next stop" goes to its stop cycle; without
    /// one, "next stop" is refused ([`Refusal::NoRow`]).
    pub field_row: bool,
}

impl Default for ExecutiveConfig {
    fn default() -> Self {
        Self {
            heartbeat_timeout_ns: 500_000_000,
            limits: MotionLimits {
                max_jog_m: 0.10,
                max_jog_rad: 0.35,
                clearance_m: ArmNodeConfig::default().cycle.clearance_m,
                at_rest_rate: 0.05,
                max_state_age_ns: 200_000_000,
                speed_fraction: MANUAL_SPEED_FRACTION,
            },
            initial_mode: OperatorModeCode::Idle,
            field_row: false,
        }
    }
}

/// The session in control.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Controller {
    /// Its session id.
    pub session_id: u64,
    /// Its client label.
    pub client: String,
    /// When it was last heard (command or heartbeat), ns.
    pub last_heard_ns: u64,
}

/// The last change of mode.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Change {
    /// When, ns.
    pub at_ns: u64,
    /// The command code behind it (0: none, e.g. heartbeat lost).
    pub code: u16,
    /// In words.
    pub reason: String,
}

/// The answer to one command.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    /// `None` when accepted.
    pub refusal: Option<Refusal>,
    /// What was done, or why not.
    pub reason: String,
    /// Planned duration of the motion started, ms (0: none).
    pub motion_duration_ms: u32,
    /// What the process must do, in order (none when refused).
    pub actions: Vec<Action>,
}

impl Decision {
    fn accepted(reason: impl Into<String>) -> Self {
        Self {
            refusal: None,
            reason: reason.into(),
            motion_duration_ms: 0,
            actions: Vec::new(),
        }
    }

    fn refused(refusal: Refusal) -> Self {
        Self {
            reason: refusal.to_string(),
            refusal: Some(refusal),
            motion_duration_ms: 0,
            actions: Vec::new(),
        }
    }

    /// True when the command was accepted.
    pub fn is_accepted(&self) -> bool {
        self.refusal.is_none()
    }

    /// Turns an accepted decision into `refusal` when carrying it out failed (a device or the
    /// row's stop cycle said no); a refused decision keeps its first refusal.
    pub fn refuse(&mut self, refusal: Refusal) {
        if self.is_accepted() {
            self.reason = refusal.to_string();
            self.refusal = Some(refusal);
        }
    }
}

/// The mode machine; see the module documentation.
#[derive(Debug, Clone)]
pub struct Executive {
    config: ExecutiveConfig,
    token: ControlToken,
    mode: OperatorModeCode,
    arms_enabled: [bool; 2],
    controller: Option<Controller>,
    last_change: Change,
    /// A manual arm motion may run until then, ns.
    arm_motion_until_ns: u64,
    /// A manual platform motion was ordered and not stopped.
    platform_motion: bool,
}

/// One arm's checked manual move.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PlannedMove {
    arm: u8,
    from: [f64; 4],
    goal: [f64; 4],
}

/// Margin after a manual move's planned end before it counts as over, ns.
const MOTION_MARGIN_NS: u64 = 500_000_000;

impl Executive {
    /// An executive at `now_ns`. The mode is the earlier executive's (`previous`, the latched
    /// `operator/mode`; a manual mode becomes idle), else `config.initial_mode`; an engaged
    /// emergency stop (`safety/emergency_stop` as latched) always wins.
    pub fn new(
        config: ExecutiveConfig,
        token: ControlToken,
        now_ns: u64,
        emergency_stop_engaged: bool,
        previous: Option<&OperatorModeState>,
    ) -> Self {
        let previous_mode = previous.and_then(OperatorModeState::mode_code);
        let (mode, reason) = if emergency_stop_engaged {
            (
                OperatorModeCode::EmergencyStopped,
                "emergency stop engaged at start".to_owned(),
            )
        } else {
            match previous_mode {
                Some(OperatorModeCode::Manual | OperatorModeCode::EmergencyStopped) => (
                    OperatorModeCode::Idle,
                    "executive restarted: idle".to_owned(),
                ),
                Some(mode) => (mode, format!("executive restarted: {}", mode.name())),
                None => (
                    config.initial_mode,
                    format!("executive started: {}", config.initial_mode.name()),
                ),
            }
        };
        let arms_enabled = previous
            .filter(|_| previous_mode.is_some())
            .map_or([true; 2], |state| state.arms_enabled.map(|flag| flag != 0));
        info!(mode = mode.name(), ?arms_enabled, %reason, "executive mode");
        Self {
            config,
            token,
            mode,
            arms_enabled,
            controller: None,
            last_change: Change {
                at_ns: now_ns,
                code: 0,
                reason,
            },
            arm_motion_until_ns: 0,
            platform_motion: false,
        }
    }

    pub fn mode(&self) -> OperatorModeCode {
        self.mode
    }

    pub fn emergency_stop_engaged(&self) -> bool {
        self.mode == OperatorModeCode::EmergencyStopped
    }

    pub fn arms_enabled(&self) -> [bool; 2] {
        self.arms_enabled
    }

    /// The session in control, if any.
    pub fn controller(&self) -> Option<&Controller> {
        self.controller.as_ref()
    }

    pub fn last_change(&self) -> &Change {
        &self.last_change
    }

    pub fn config(&self) -> &ExecutiveConfig {
        &self.config
    }

    fn set_mode(&mut self, now_ns: u64, mode: OperatorModeCode, code: u16, reason: String) {
        if mode != self.mode {
            info!(from = self.mode.name(), to = mode.name(), %reason, "mode changed");
        }
        self.mode = mode;
        self.last_change = Change {
            at_ns: now_ns,
            code,
            reason,
        };
    }

    fn live(&self, controller: &Controller, now_ns: u64) -> bool {
        now_ns.saturating_sub(controller.last_heard_ns) <= self.config.heartbeat_timeout_ns
    }

    /// Decides on one command (module docs).
    pub fn handle(&mut self, now_ns: u64, message: &OperatorCommand, view: &StackView) -> Decision {
        let decision = self.decide(now_ns, message, view);
        match &decision.refusal {
            None => info!(code = message.code, client = %message.client,
                reason = %decision.reason, "operator command accepted"),
            Some(refusal) => warn!(code = message.code, client = %message.client,
                %refusal, "operator command refused"),
        }
        decision
    }

    fn decide(&mut self, now_ns: u64, message: &OperatorCommand, view: &StackView) -> Decision {
        let command = match Command::decode(message) {
            Ok(command) => command,
            Err(refusal) => return Decision::refused(refusal),
        };
        let token = message.token.as_str();
        let client = message.client.as_str();
        let code = message.code;
        // The stop needs no authority: before the token, the session and the mode.
        if command == Command::EmergencyStop {
            let with_token = !token.is_empty() && self.token.matches(token);
            return self.emergency_stop(now_ns, code, client, with_token);
        }
        if token.is_empty() {
            return Decision::refused(Refusal::MissingToken);
        }
        if !self.token.matches(token) {
            return Decision::refused(Refusal::WrongToken);
        }
        if message.session_id == 0 {
            return Decision::refused(Refusal::BadArgument("session id 0".to_owned()));
        }
        if command == Command::LeaveControl {
            return match &self.controller {
                Some(c) if c.session_id == message.session_id => {
                    self.controller = None;
                    Decision::accepted("control left")
                }
                _ => Decision::accepted("not in control"),
            };
        }
        if let Some(controller) = &self.controller
            && controller.session_id != message.session_id
            && self.live(controller, now_ns)
        {
            return Decision::refused(Refusal::OtherSessionInControl {
                client: controller.client.clone(),
                age_ms: now_ns.saturating_sub(controller.last_heard_ns) / 1_000_000,
            });
        }
        match &mut self.controller {
            Some(c) if c.session_id == message.session_id => c.last_heard_ns = now_ns,
            _ => {
                info!(%client, session = message.session_id, "control taken");
                self.controller = Some(Controller {
                    session_id: message.session_id,
                    client: client.to_owned(),
                    last_heard_ns: now_ns,
                });
            }
        }
        let by = |what: &str| format!("{what} by {client}");
        let mode = self.mode;
        let name = command.name();
        match command {
            Command::Heartbeat => Decision::accepted("in control"),
            Command::Start => match mode {
                OperatorModeCode::Idle | OperatorModeCode::Paused | OperatorModeCode::Manual => {
                    let mut decision = Decision::accepted("harvesting");
                    decision.actions = self.stop_manual_motion(mode);
                    self.set_mode(now_ns, OperatorModeCode::Harvesting, code, by("started"));
                    decision
                }
                _ => Decision::refused(Refusal::forbidden(name, mode)),
            },
            Command::Pause => match mode {
                OperatorModeCode::Harvesting => {
                    self.set_mode(now_ns, OperatorModeCode::Paused, code, by("paused"));
                    Decision::accepted("paused: no new approach; attempts under way finish")
                }
                _ => Decision::refused(Refusal::forbidden(name, mode)),
            },
            Command::Resume => match mode {
                OperatorModeCode::Paused => {
                    self.set_mode(now_ns, OperatorModeCode::Harvesting, code, by("resumed"));
                    Decision::accepted("harvesting")
                }
                _ => Decision::refused(Refusal::forbidden(name, mode)),
            },
            Command::Stop => match mode {
                OperatorModeCode::EmergencyStopped => {
                    Decision::refused(Refusal::forbidden(name, mode))
                }
                OperatorModeCode::Idle => Decision::accepted("already idle"),
                _ => {
                    let mut decision = Decision::accepted("idle");
                    decision.actions = self.stop_manual_motion(mode);
                    self.set_mode(now_ns, OperatorModeCode::Idle, code, by("stopped"));
                    decision
                }
            },
            Command::Release => match mode {
                OperatorModeCode::EmergencyStopped => {
                    let mut decision = Decision::accepted("emergency stop released: idle");
                    decision.actions.push(Action::ReleaseEmergencyStop);
                    self.set_mode(
                        now_ns,
                        OperatorModeCode::Idle,
                        code,
                        by("emergency stop released"),
                    );
                    decision
                }
                _ => Decision::refused(Refusal::ForbiddenByMode {
                    command: name,
                    mode: mode.name(),
                    hint: ": the emergency stop is not engaged",
                }),
            },
            Command::SetArmEnabled { arm, enabled } => {
                self.arms_enabled[usize::from(arm - 1)] = enabled;
                let what = if enabled { "enabled" } else { "disabled" };
                info!(arm, enabled, %client, "arm {what}");
                Decision::accepted(format!("arm {arm} {what}"))
            }
            Command::Home => self.manual_moves(now_ns, message, view, &[1, 2], None),
            Command::DropOff { arm } => self.manual_moves(now_ns, message, view, &[arm], None),
            Command::Jog { arm, joint, delta } => {
                self.manual_moves(now_ns, message, view, &[arm], Some((joint, delta)))
            }
            Command::PlatformMove { target_m } => {
                self.platform_move(now_ns, message, view, target_m)
            }
            Command::NextStop => self.next_stop(mode),
            Command::EmergencyStop | Command::LeaveControl => Decision::accepted("handled above"),
        }
    }

    /// "Next stop": only with a row and while harvesting (the stop cycle runs only then); the
    /// process carries out [`Action::NextStop`] and the stop cycle may still refuse.
    fn next_stop(&self, mode: OperatorModeCode) -> Decision {
        if !self.config.field_row {
            return Decision::refused(Refusal::NoRow);
        }
        if mode != OperatorModeCode::Harvesting {
            return Decision::refused(Refusal::forbidden(Command::NextStop.name(), mode));
        }
        let mut decision = Decision::accepted("next stop: advancing");
        decision.actions.push(Action::NextStop);
        decision
    }

    /// The operator's emergency stop, from anyone (`with_token`: the sender showed the control
    /// token; said in the reason so the log tells who stopped the robot and with what right).
    fn emergency_stop(
        &mut self,
        now_ns: u64,
        code: u16,
        client: &str,
        with_token: bool,
    ) -> Decision {
        let already = self.mode == OperatorModeCode::EmergencyStopped;
        let reason = if with_token {
            format!("emergency stop by {client}")
        } else {
            format!("emergency stop by {client} (without the control token)")
        };
        let mut decision = Decision::accepted(if already {
            "emergency stop already engaged"
        } else {
            "emergency stop engaged"
        });
        decision.actions.push(Action::EngageEmergencyStop {
            reason: reason.clone(),
        });
        decision
            .actions
            .extend(self.stop_manual_motion(OperatorModeCode::Manual));
        if !already {
            self.set_mode(now_ns, OperatorModeCode::EmergencyStopped, code, reason);
        }
        decision
    }

    /// The protective stop the independent safety monitor asks for (`safety/violation` with
    /// action `stop`): the emergency stop is engaged from any mode, without token or session
    /// (the monitor holds no operator credential and can only ask for a stop, never release
    /// it). Returns the actions to carry out; none when the stop is already engaged, so a
    /// burst of violations publishes the stop once.
    pub fn protective_stop(&mut self, now_ns: u64, violation: &str) -> Vec<Action> {
        if self.mode == OperatorModeCode::EmergencyStopped {
            return Vec::new();
        }
        let reason = format!("protective stop, safety monitor: {violation}");
        warn!(%reason, "protective stop");
        let mut actions = vec![Action::EngageEmergencyStop {
            reason: reason.clone(),
        }];
        actions.extend(self.stop_manual_motion(self.mode));
        self.set_mode(now_ns, OperatorModeCode::EmergencyStopped, 0, reason);
        actions
    }

    /// Stop orders for any manual motion when leaving `from`.
    fn stop_manual_motion(&mut self, from: OperatorModeCode) -> Vec<Action> {
        if from != OperatorModeCode::Manual {
            return Vec::new();
        }
        self.arm_motion_until_ns = 0;
        self.platform_motion = false;
        vec![
            Action::ArmStop { arm: 1 },
            Action::ArmStop { arm: 2 },
            Action::PlatformStop,
        ]
    }

    fn manual_mode_allowed(&self, name: &'static str) -> Result<(), Refusal> {
        match self.mode {
            OperatorModeCode::Idle | OperatorModeCode::Paused | OperatorModeCode::Manual => Ok(()),
            mode => Err(Refusal::forbidden(name, mode)),
        }
    }

    /// The moves of home (both arms), drop-off (one arm, `jog` none) or a jog of one arm,
    /// checked.
    fn plan_moves(
        &self,
        name: &'static str,
        view: &StackView,
        arms: &[u8],
        jog: Option<(JointName, f64)>,
    ) -> Result<Vec<PlannedMove>, Refusal> {
        self.manual_mode_allowed(name)?;
        let limits = &self.config.limits;
        let mut moves = Vec::new();
        for &arm in arms {
            let here =
                motion_check::idle_at_rest(arm, view.arms[usize::from(arm - 1)].as_ref(), limits)?;
            let goal = match jog {
                Some((joint, delta)) => {
                    motion_check::jog_goal(arm, &here.joint_position, joint, delta, limits)?
                }
                None => motion_check::drop_off_pose(arm),
            };
            moves.push(PlannedMove {
                arm,
                from: here.joint_position,
                goal,
            });
        }
        for planned in &moves {
            let other = 3 - planned.arm;
            let (other_from, other_goal) = match moves.iter().find(|m| m.arm == other) {
                Some(m) => (m.from, m.goal),
                None => {
                    let view: &ArmView = view.arms[usize::from(other - 1)]
                        .as_ref()
                        .filter(|v| v.age_ns <= limits.max_state_age_ns)
                        .ok_or(Refusal::ArmStateUnknown(other))?;
                    (view.joint_position, view.joint_position)
                }
            };
            motion_check::check_clearance(
                planned.arm,
                &planned.from,
                &planned.goal,
                &other_from,
                &other_goal,
                limits,
            )?;
        }
        Ok(moves)
    }

    /// Home (both arms), drop-off (one arm, `jog` none) or a jog of one arm.
    fn manual_moves(
        &mut self,
        now_ns: u64,
        message: &OperatorCommand,
        view: &StackView,
        arms: &[u8],
        jog: Option<(JointName, f64)>,
    ) -> Decision {
        let name = message
            .command_code()
            .map_or("manual move", |code| code.name());
        let moves = match self.plan_moves(name, view, arms, jog) {
            Ok(moves) => moves,
            Err(refusal) => return Decision::refused(refusal),
        };
        let mut duration_ms = 0;
        for m in &moves {
            match motion_check::duration_ms(m.arm, &m.from, &m.goal, &self.config.limits) {
                Ok(ms) => duration_ms = duration_ms.max(ms),
                Err(refusal) => return Decision::refused(refusal),
            }
        }
        let mut decision = Decision::accepted(match jog {
            Some((joint, delta)) => format!(
                "arm {} {} {:+.3} {}",
                arms[0],
                joint.name(),
                delta,
                joint.unit()
            ),
            None if arms.len() == 2 => "both arms to their drop-off pose".to_owned(),
            None => format!("arm {} to its drop-off pose", arms[0]),
        });
        decision.motion_duration_ms = duration_ms;
        for m in moves {
            decision.actions.push(Action::ArmMoveTo {
                arm: m.arm,
                goal: m.goal,
                speed_fraction: self.config.limits.speed_fraction,
                request_id: message.request_id,
            });
        }
        self.arm_motion_until_ns = self
            .arm_motion_until_ns
            .max(now_ns + u64::from(duration_ms) * 1_000_000 + MOTION_MARGIN_NS);
        let reason = format!("{} by {}", decision.reason, message.client.as_str());
        self.set_mode(now_ns, OperatorModeCode::Manual, message.code, reason);
        decision
    }

    fn platform_move(
        &mut self,
        now_ns: u64,
        message: &OperatorCommand,
        view: &StackView,
        target_m: [f64; 2],
    ) -> Decision {
        let checked = (|| -> Result<(), Refusal> {
            self.manual_mode_allowed("platform")?;
            let platform = view.platform.ok_or(Refusal::NoPlatform)?;
            for (i, axis) in ["in-out", "up-down"].into_iter().enumerate() {
                let value = target_m[i];
                let max = platform.travel_max_m[i];
                if !(value.is_finite() && (0.0..=max).contains(&value)) {
                    return Err(Refusal::PlatformOutsideTravel { axis, value, max });
                }
            }
            // The platform never moves while an arm picks or moves.
            for arm in [1u8, 2] {
                motion_check::idle_at_rest(
                    arm,
                    view.arms[usize::from(arm - 1)].as_ref(),
                    &self.config.limits,
                )?;
            }
            Ok(())
        })();
        if let Err(refusal) = checked {
            return Decision::refused(refusal);
        }
        let mut decision = Decision::accepted(format!(
            "platform to {:.3} m in-out, {:.3} m up-down",
            target_m[0], target_m[1]
        ));
        decision.actions.push(Action::PlatformMoveTo { target_m });
        self.platform_motion = true;
        let reason = format!("{} by {}", decision.reason, message.client.as_str());
        self.set_mode(now_ns, OperatorModeCode::Manual, message.code, reason);
        decision
    }

    /// Time passes: a controlling session silent for the heartbeat timeout loses control, and
    /// a manual motion under way is stopped (the mode stays manual).
    pub fn tick(&mut self, now_ns: u64, view: &StackView) -> Vec<Action> {
        let silent = match &self.controller {
            Some(controller) => !self.live(controller, now_ns),
            None => true,
        };
        if !silent {
            return Vec::new();
        }
        let mut actions = Vec::new();
        if self.mode == OperatorModeCode::Manual {
            let arm_moving = now_ns < self.arm_motion_until_ns;
            let platform_moving =
                self.platform_motion && view.platform.is_some_and(|p| p.in_motion);
            if arm_moving || platform_moving {
                let client = self
                    .controller
                    .as_ref()
                    .map_or_else(|| "no session".to_owned(), |c| c.client.clone());
                warn!(%client, "controlling session silent: manual motion stopped");
                actions = self.stop_manual_motion(OperatorModeCode::Manual);
                let reason = format!(
                    "heartbeat of {client} lost for {} ms: manual motion stopped",
                    self.config.heartbeat_timeout_ns / 1_000_000
                );
                self.set_mode(now_ns, OperatorModeCode::Manual, 0, reason);
            } else if !platform_moving {
                self.platform_motion = false;
            }
        }
        if let Some(controller) = self.controller.take() {
            info!(client = %controller.client, "control lapsed (session silent)");
        }
        actions
    }

    /// Fills the `operator/mode` sample (platform fields are the caller's).
    pub fn fill_state(&self, state: &mut OperatorModeState) {
        state.mode = self.mode as u8;
        state.emergency_stop_engaged = u8::from(self.emergency_stop_engaged());
        state.arms_enabled = self.arms_enabled.map(u8::from);
        state._reserved = [0; 1];
        state.controlling_session = self.controller.as_ref().map_or(0, |c| c.session_id);
        state.controller =
            FixedString::new(self.controller.as_ref().map_or("", |c| c.client.as_str()));
        state.last_change_ns = self.last_change.at_ns;
        state.last_change_code = self.last_change.code;
        state._reserved2 = [0; 6];
        state.last_change_reason = FixedString::new(&self.last_change.reason);
    }
}

#[cfg(test)]
mod tests;
