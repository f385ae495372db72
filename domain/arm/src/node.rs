//! The arm process's logic without any transport: [`ArmNode`] turns one control tick's inputs
//! (time, encoder feedback, the target assigned on `armN/target`, the vacuum supervisor's state
//! and answers, the other arm's state, the emergency stop) into that tick's outputs (servo
//! set-points, the standing valve request, the `ArmState` to publish and what happened).
//!
//! Inside, one [`PickingCycle`] runs the four phases of [dual-arm sec. 3.3] (Fig. 9a) with the
//! tracking controller of eq. 5-6. The node adds what the process needs around it:
//!
//! - **Targets.** A new `ArmTarget` (new `msg_seq`) is offered to the cycle every tick while the
//!   arm is idle until it is accepted or refused for good. Refusals that depend on the moment
//!   (the other arm's swept path, the runtime safety check of section 3.3; stale feedback) are
//!   retried; the others (outside the workspace, NaN, stale detection) drop the target. The
//!   target carries the apple centre and radius; the picking point handed to the cycle is
//!   [`picking_point_m`]. The published state tells the vacuum supervisor what became of the
//!   newest target not taken up (`ArmState::target_status`: waiting after a refusal for the
//!   moment, or refused for good), so that it can hand the apple elsewhere without waiting
//!   for its dispatch timeout. A target with apple id 0 withdraws the one not taken up yet.
//! - **Servo set-points.** The cycle commands joint rates; the servo trait takes position
//!   set-points with feed-forward rates. The node integrates its own rate commands into a
//!   position set-point valid at the tick (resynchronised to the encoders when it starts, after
//!   a brake, or if the arm fell more than [`ArmNodeConfig::setpoint_resync_m`] /
//!   [`ArmNodeConfig::setpoint_resync_rad`] behind), clamped to the Table 1 limits, so no
//!   out-of-limit set-point is ever sent. A stopped controller brakes the drives.
//! - **Valve.** The cycle's valve wish becomes a standing `ValveRequest` (new `request_seq` on
//!   every change). What the cycle is told about the valve comes from `VacuumState`: "open"
//!   only once the inlet gate of this arm is at its open end stop and the vent closed (granted
//!   and arrived), "closed" only once the inlet is at its closed end stop and the tube vented
//!   below [`ArmNodeConfig::vented_vacuum_mmh2o`] (the apple falls only then). The attachment
//!   is the vacuum supervisor's debounced pressure inference (`ArmAttachment::Sealed`).
//! - **Emergency stop.** While engaged: the drives brake, the valve request is `Close`, the
//!   phase is `Stopped`, any running cycle is abandoned (its attempt ends with cause
//!   [`AttemptFailure::EmergencyStop`]) and targets received meanwhile are dropped. After
//!   release the arm is idle where it stopped; the next target starts from there.
//! - **Missed deadlines.** A tick that comes more than
//!   [`CycleConfig::max_tick_gap_periods`] nominal periods after the previous one (the control
//!   loop was held up) brakes the drives for that tick, as a feedback outage does; the running
//!   motion restarts from where the arm is on the next tick on time (`CycleEvent::DeadlineMissed`).
//!
//! - **Operator.** While the operator holds new targets ([`ArmNode::hold_targets`]: paused,
//!   idle, manual, or this arm disabled) a target is not offered to the cycle; the arm reports
//!   it as waiting, so the vacuum supervisor takes it back. An attempt under way runs to its
//!   end. A manual move ([`ArmNode::start_manual`], `crate::manual_motion`) runs only while the
//!   cycle is idle and no emergency stop is engaged; the emergency stop ends it.
//!
//! Pure logic: no clock reads, no I/O. Per-tick work allocates nothing after the first ticks
//! (the event buffer is reused).

use harvest_ipc::Header;
use harvest_ipc::payloads::arm::TargetStatus;
use harvest_ipc::payloads::{
    ArmAttachment, ArmPhase as PhaseCode, ArmState, ArmTarget, VacuumState, ValveGrant,
    ValveRequest, ValveRequestKind,
};
use thiserror::Error;
use tracing::{debug, info, trace, warn};

use crate::manual_motion::{ManualMotion, ManualMotionError};
use crate::picking_cycle::{
    CycleConfig, CycleConfigError, CycleEvent, CycleInput, CyclePhase, OtherArmState, PickingCycle,
    TargetDecision, TargetRejection, TargetRequest, ValveRequest as CycleValve,
};
use crate::reported_phase::{cycle_phase_of_reported, reported_phase};
use harvest_robot_model::clearance::SweptPath;
use harvest_robot_model::joint::{JointPosition, JointVelocity};
use harvest_robot_model::kinematics::{forward, inverse};
use harvest_robot_model::params::{ArmId, ArmParams};

/// Radius assumed when a target carries none (not finite or <= 0), m (choice: a medium apple,
/// 80 mm across).
pub const DEFAULT_APPLE_RADIUS_M: f64 = 0.04;

/// Where the cup should be to pick an apple of centre `apple_center_m` and radius `radius_m`
/// (robot frame, m): on the apple's surface facing the robot, `contact_gap_m` short of it along
/// -x (the tube approaches along +x, toward the canopy). The cup seals within 1.5 cm of the
/// surface (section 2.2), so a gap of 0 leaves the whole tolerance for localization error.
pub fn picking_point_m(apple_center_m: [f64; 3], radius_m: f64, contact_gap_m: f64) -> [f64; 3] {
    let radius_m = if radius_m.is_finite() && radius_m > 0.0 {
        radius_m
    } else {
        DEFAULT_APPLE_RADIUS_M
    };
    let [x, y, z] = apple_center_m;
    [x - radius_m - contact_gap_m, y, z]
}

/// Algorithm 1's `dist_i(p) < inf` for this robot: whether `arm` can pick the apple of centre
/// `apple_center_m` and radius `radius_m` (robot frame, m) without waiting for the other arm to
/// move. True when the picking point ([`picking_point_m`]) has an inverse of eq. 1 inside the
/// Table 1 limits and, with another arm present, the joint-space path from home through the
/// approach stand-off to the picking point keeps the cycle's clearance from the other arm
/// resting at its home pose (the same swept-tube test the picking cycle runs before it moves).
/// An apple between the arms that neither can reach past the other's resting tube is thus
/// reachable by neither and is left out of the assignment, instead of being refused at run
/// time.
pub fn pick_reachable(
    arm: ArmId,
    apple_center_m: [f64; 3],
    radius_m: f64,
    config: &ArmNodeConfig,
) -> bool {
    let params = ArmParams::for_arm(arm);
    let pick = picking_point_m(apple_center_m, radius_m, config.contact_gap_m);
    let Ok(goal) = inverse(&params, pick) else {
        return false;
    };
    if !config.other_arm_present {
        return true;
    }
    let other = ArmParams::for_arm(arm.other());
    let standoff = [pick[0] - config.cycle.approach_standoff_m, pick[1], pick[2]];
    let via = inverse(&params, standoff).unwrap_or(goal);
    let mut ours = SweptPath::new();
    ours.push_joint_line(&params.links, &params.home, &via, 8);
    ours.push_joint_line(&params.links, &via, &goal, 2);
    let mut theirs = SweptPath::new();
    theirs.push(&other.links, &other.home);
    ours.min_distance_m(&theirs) >= config.cycle.clearance_m
}

/// Index of an arm's inlet valve (1 or 3 on the board) in 4-valve arrays; the vent is the next.
fn inlet_index(arm: ArmId) -> usize {
    match arm {
        ArmId::Arm1 => 0,
        ArmId::Arm2 => 2,
    }
}

/// Tunables of the node; defaults are documented choices.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmNodeConfig {
    /// The picking cycle's settings. Default: [`CycleConfig::default`] with
    /// `valve_grant_timeout_s` 10 s (under the 2023 policy an arm waits at its apple for a whole
    /// attach-retract-release of the other arm, section 4.2) and `attach_timeout_s` 0.3 s (the
    /// vacuum supervisor declares a failed attachment 0.25 s after the gate opened; the arm
    /// gives up just after it, eq. 8 third clause).
    pub cycle: CycleConfig,
    /// Gap between cup and apple surface at the picking point, m (default 0, see
    /// [`picking_point_m`]).
    pub contact_gap_m: f64,
    /// Prismatic lag behind the set-point that resynchronises it to the encoder, m (default
    /// 0.01).
    pub setpoint_resync_m: f64,
    /// Revolute lag behind the set-point that resynchronises it to the encoder, rad (default
    /// 0.02, 1.8 cm at the 0.9 m tube tip).
    pub setpoint_resync_rad: f64,
    /// Arm tube vacuum below which the tube counts as vented, mmH2O (default 150: 2.8 N of
    /// suction at 47 N per 2500 mmH2O, about a 250 g apple's weight).
    pub vented_vacuum_mmh2o: f32,
    /// Oldest other-arm state used for the clearance check, s (default 0.1 s = 20 periods). An
    /// older or missing state defers new targets: no motion starts blind.
    pub max_other_arm_age_s: f64,
    /// Whether another arm shares the workspace (default true). When false, targets are
    /// checked without an other arm.
    pub other_arm_present: bool,
}

impl Default for ArmNodeConfig {
    fn default() -> Self {
        Self {
            cycle: CycleConfig {
                valve_grant_timeout_s: 10.0,
                attach_timeout_s: 0.3,
                ..CycleConfig::default()
            },
            contact_gap_m: 0.0,
            setpoint_resync_m: 0.01,
            setpoint_resync_rad: 0.02,
            vented_vacuum_mmh2o: 150.0,
            max_other_arm_age_s: 0.1,
            other_arm_present: true,
        }
    }
}

/// Why an [`ArmNode`] could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ArmNodeError {
    /// The picking cycle refused its configuration.
    #[error("arm node picking cycle: {0}")]
    Cycle(#[from] CycleConfigError),
    /// A node setting is out of range.
    #[error("arm node config `{field}` = {value}: must be finite and {expected}")]
    Invalid {
        /// Field name.
        field: &'static str,
        /// Its value.
        value: f64,
        /// What was expected.
        expected: &'static str,
    },
}

/// Encoder feedback as read from the servos (the `ArmServos::feedback` sample).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct EncoderSample {
    /// When the encoders were sampled, ns (stack clock).
    pub capture_ns: u64,
    /// `[D m, theta rad, phi rad, twist rad]`.
    pub position: [f64; 4],
    /// `[m/s, rad/s, rad/s, rad/s]`.
    pub velocity: [f64; 4],
}

/// The other arm as this arm sees it: its last state and the target it was given (for the
/// goal of its approach).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OtherArmInput<'a> {
    /// Its last published state.
    pub state: &'a ArmState,
    /// Its current target, if any.
    pub target: Option<&'a ArmTarget>,
}

/// One tick's inputs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmNodeInput<'a> {
    /// Now, ns (stack clock).
    pub now_ns: u64,
    /// Newest encoder feedback, if any arrived.
    pub feedback: Option<EncoderSample>,
    /// Latest sample on this arm's target channel (history 1), if any.
    pub target: Option<&'a ArmTarget>,
    /// Latest vacuum state.
    pub vacuum: Option<&'a VacuumState>,
    /// The vacuum supervisor's latest answer to this arm, if any.
    pub grant: Option<&'a ValveGrant>,
    /// The other arm, if its state has been received.
    pub other_arm: Option<OtherArmInput<'a>>,
    /// True while the emergency stop is engaged.
    pub emergency_stop: bool,
}

/// What the servos must do this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ServoOrder {
    /// Track the position set-point (valid now) with the feed-forward rates.
    Track {
        /// `[D m, theta rad, phi rad, twist rad]`, inside the joint limits.
        position: [f64; 4],
        /// `[m/s, rad/s, rad/s, rad/s]`.
        velocity: [f64; 4],
    },
    /// Brake: hold the current position.
    Hold,
}

/// How an attempt ended without an apple, from the arm's point of view.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum AttemptFailure {
    /// The arm did not settle at the apple in time.
    ApproachTimeout,
    /// The vacuum supervisor never opened the valve in time.
    ValveNotGranted,
    /// The pressure never showed a seal within the attach timeout.
    NoAttachment,
    /// The seal was lost after attaching (apple slipped or dropped).
    AppleLost,
    /// At the drop-off the valve never reported closed.
    ValveNotClosed,
    /// The emergency stop abandoned the cycle.
    EmergencyStop,
}

impl AttemptFailure {
    fn from_event(event: CycleEvent) -> Option<Self> {
        match event {
            CycleEvent::ApproachTimeout => Some(Self::ApproachTimeout),
            CycleEvent::ValveGrantTimeout => Some(Self::ValveNotGranted),
            CycleEvent::AttachFailed => Some(Self::NoAttachment),
            CycleEvent::AppleLost => Some(Self::AppleLost),
            CycleEvent::ValveCloseTimeout => Some(Self::ValveNotClosed),
            _ => None,
        }
    }
}

/// Why a target was not offered to the cycle this tick (retried next tick).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum DeferReason {
    /// The other arm's state is missing or older than `max_other_arm_age_s`.
    OtherArmUnknown,
}

/// Something the node did or saw this tick.
#[derive(Debug, Clone, PartialEq)]
pub enum ArmNodeEvent {
    /// A new target arrived.
    TargetReceived {
        /// Its apple id.
        apple_id: u32,
    },
    /// The cycle took the target: the approach started.
    TargetAccepted {
        /// Its apple id.
        apple_id: u32,
    },
    /// The cycle refused the target; `will_retry` when the refusal depends on the moment.
    /// Repeated identical refusals are reported once.
    TargetRejected {
        /// Its apple id.
        apple_id: u32,
        /// Why.
        reason: TargetRejection,
        /// True when the target is offered again next tick.
        will_retry: bool,
    },
    /// The node held the target back (reported once per reason).
    TargetDeferred {
        /// Its apple id.
        apple_id: u32,
        /// Why.
        reason: DeferReason,
    },
    /// The published phase changed.
    PhaseChanged {
        /// Phase before.
        from: PhaseCode,
        /// Phase after.
        to: PhaseCode,
    },
    /// A picking-cycle event (approach complete, attached, apple lost, ...).
    Cycle(CycleEvent),
    /// The standing valve request changed.
    ValveRequested {
        /// The new request.
        kind: ValveRequestKind,
        /// Its sequence number.
        request_seq: u32,
    },
    /// The vacuum supervisor refused the current valve request (reported once per reason).
    ValveRefused {
        /// The supervisor's reason code.
        reason_code: u8,
    },
    /// An attempt ended.
    AttemptEnded {
        /// The apple.
        apple_id: u32,
        /// True when the apple was released at the drop-off.
        harvested: bool,
        /// Why not, from the arm's events.
        failure: Option<AttemptFailure>,
    },
    /// The emergency stop was engaged (true) or released (false).
    EmergencyStop {
        /// New state.
        engaged: bool,
    },
}

/// One tick's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmNodeOutput {
    /// What the servos must do.
    pub servo: ServoOrder,
    /// The standing valve request (publish on change; `request_seq` changes with it).
    pub valve_request: ValveRequest,
    /// The state to publish on `armN/state`.
    pub state: ArmState,
    /// The end-effector goal of the running motion, robot frame, m.
    pub goal_m: Option<[f64; 3]>,
    /// What happened this tick.
    pub events: Vec<ArmNodeEvent>,
}

/// The running attempt.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Attempt {
    apple_id: u32,
    failure: Option<AttemptFailure>,
    harvested: bool,
}

/// The arm process's logic; see the module documentation.
#[derive(Debug, Clone)]
pub struct ArmNode {
    arm: ArmId,
    params: ArmParams,
    other_params: ArmParams,
    config: ArmNodeConfig,
    cycle: PickingCycle,
    /// Newest target not yet taken or refused for good.
    pending: Option<ArmTarget>,
    last_target_seq: Option<u64>,
    last_rejection: Option<std::mem::Discriminant<TargetRejection>>,
    deferred: bool,
    /// What became of the newest target not taken up, and its apple id (`ArmState`).
    target_status: (TargetStatus, u32),
    attempt: Option<Attempt>,
    setpoint: Option<[f64; 4]>,
    last_rate: [f64; 4],
    last_now_ns: Option<u64>,
    last_joints: Option<([f64; 4], [f64; 4], u64)>,
    phase: PhaseCode,
    stopped: bool,
    valve_kind: ValveRequestKind,
    request_seq: u32,
    last_refusal: Option<(u32, u8)>,
    state_seq: u64,
    harvested_count: u32,
    output: ArmNodeOutput,
    /// New targets are held back (operator: not harvesting, or this arm disabled).
    targets_held: bool,
    /// The manual move under way.
    manual: Option<ManualMotion>,
}

/// Why a manual move was not started.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ManualRefusal {
    /// The emergency stop is engaged.
    #[error("emergency stop engaged")]
    EmergencyStop,
    /// The picking cycle is not idle.
    #[error("arm busy in its picking cycle ({0:?})")]
    Busy(PhaseCode),
    /// No encoder feedback yet.
    #[error("no encoder feedback yet")]
    NoFeedback,
    /// The move cannot be planned (limits, not finite).
    #[error(transparent)]
    Plan(#[from] ManualMotionError),
}

impl ArmNode {
    /// The node of `arm` (Table 1 parameters), checking clearance against the other arm.
    pub fn new(arm: ArmId, config: ArmNodeConfig) -> Result<Self, ArmNodeError> {
        for (field, value, expected) in [
            ("contact_gap_m", config.contact_gap_m, "finite"),
            ("setpoint_resync_m", config.setpoint_resync_m, "> 0"),
            ("setpoint_resync_rad", config.setpoint_resync_rad, "> 0"),
            (
                "vented_vacuum_mmh2o",
                f64::from(config.vented_vacuum_mmh2o),
                "> 0",
            ),
            ("max_other_arm_age_s", config.max_other_arm_age_s, "> 0"),
        ] {
            let ok = value.is_finite() && (field == "contact_gap_m" || value > 0.0);
            if !ok {
                return Err(ArmNodeError::Invalid {
                    field,
                    value,
                    expected,
                });
            }
        }
        let params = ArmParams::for_arm(arm);
        let other_params = ArmParams::for_arm(arm.other());
        let cycle = PickingCycle::new(params, other_params, config.cycle)?;
        let valve_request = ValveRequest {
            arm_id: arm.number(),
            kind: ValveRequestKind::Close.into(),
            ..ValveRequest::default()
        };
        Ok(Self {
            arm,
            params,
            other_params,
            config,
            cycle,
            pending: None,
            last_target_seq: None,
            last_rejection: None,
            deferred: false,
            target_status: (TargetStatus::None, 0),
            attempt: None,
            setpoint: None,
            last_rate: [0.0; 4],
            last_now_ns: None,
            last_joints: None,
            phase: PhaseCode::Idle,
            stopped: false,
            valve_kind: ValveRequestKind::Close,
            request_seq: 0,
            last_refusal: None,
            state_seq: 0,
            harvested_count: 0,
            output: ArmNodeOutput {
                servo: ServoOrder::Hold,
                valve_request,
                state: ArmState {
                    arm_id: arm.number(),
                    ..ArmState::default()
                },
                goal_m: None,
                events: Vec::with_capacity(8),
            },
            targets_held: false,
            manual: None,
        })
    }

    /// Which arm.
    pub fn arm(&self) -> ArmId {
        self.arm
    }

    /// The arm's parameters (Table 1).
    pub fn params(&self) -> &ArmParams {
        &self.params
    }

    /// The node's settings.
    pub fn config(&self) -> &ArmNodeConfig {
        &self.config
    }

    /// Holds new targets back (true) or lets them be offered again (false); see the module
    /// documentation.
    pub fn hold_targets(&mut self, held: bool) {
        if held != self.targets_held {
            info!(arm = %self.arm, held, "new targets {}", if held { "held" } else { "allowed" });
        }
        self.targets_held = held;
    }

    /// True while a manual move runs.
    pub fn manual_active(&self) -> bool {
        self.manual.is_some()
    }

    /// Starts a manual move to `goal` (`[D m, theta rad, phi rad, twist rad]`) at
    /// `speed_fraction` of the rate limits, from the last encoder position; returns its duration,
    /// s. A move under way is replaced.
    pub fn start_manual(
        &mut self,
        now_ns: u64,
        goal: [f64; 4],
        speed_fraction: f64,
        request_id: u64,
    ) -> Result<f64, ManualRefusal> {
        if self.stopped {
            return Err(ManualRefusal::EmergencyStop);
        }
        if self.cycle.phase() != CyclePhase::Idle {
            return Err(ManualRefusal::Busy(self.phase));
        }
        let Some((from, _, _)) = self.last_joints else {
            return Err(ManualRefusal::NoFeedback);
        };
        // From the set-point the servos track, if any, so the move starts without a jump.
        let from = self.setpoint.unwrap_or(from);
        let motion = ManualMotion::plan(
            &self.params,
            &from,
            &goal,
            speed_fraction,
            now_ns,
            request_id,
        )?;
        let duration_s = motion.duration_s();
        info!(arm = %self.arm, request_id, ?goal, duration_s, "manual move started");
        self.manual = Some(motion);
        Ok(duration_s)
    }

    /// Ends the manual move under way (the arm holds where its set-point is).
    pub fn stop_manual(&mut self) {
        if let Some(motion) = self.manual.take() {
            info!(arm = %self.arm, request_id = motion.request_id(), "manual move stopped");
            self.last_rate = [0.0; 4];
        }
    }

    /// Apples released at the drop-off so far.
    pub fn harvested_count(&self) -> u32 {
        self.harvested_count
    }

    /// The other arm as the picking cycle's clearance check needs it: phase, end-effector and,
    /// while it approaches or attaches, the picking point of its target.
    pub fn other_arm_view(&self, other: &OtherArmInput<'_>) -> OtherArmState {
        let state = other.state;
        let phase = cycle_phase_of_reported(state.phase.get().ok());
        let goal_m = other
            .target
            .filter(|t| t.apple_id == state.apple_id)
            .filter(|_| matches!(phase, CyclePhase::Approach | CyclePhase::Attach))
            .map(|t| picking_point_m(t.position_in_robot_m, t.radius_m, self.config.contact_gap_m));
        OtherArmState {
            phase,
            end_effector_m: state.end_effector_in_robot_m,
            goal_m,
        }
    }

    /// The outputs of the last [`Self::step`] (empty before the first).
    pub fn last_output(&self) -> &ArmNodeOutput {
        &self.output
    }

    /// One control tick; see the module documentation. The returned outputs stay valid until
    /// the next call.
    pub fn step(&mut self, input: &ArmNodeInput<'_>) -> &ArmNodeOutput {
        self.output.events.clear();
        let now_ns = input.now_ns;
        let dt_s = match self.last_now_ns {
            Some(last) if now_ns > last => (now_ns - last) as f64 * 1e-9,
            Some(_) => 0.0,
            None => self.config.cycle.nominal_period_s,
        };
        let period_ns = self
            .last_now_ns
            .map_or(0, |last| now_ns.saturating_sub(last));
        self.last_now_ns = Some(now_ns);
        if let Some(f) = input.feedback {
            self.last_joints = Some((f.position, f.velocity, f.capture_ns));
        }
        self.take_new_target(input.target);

        if input.emergency_stop {
            self.emergency_stop(period_ns);
            return &self.output;
        }
        if self.stopped {
            self.stopped = false;
            info!(arm = %self.arm, "emergency stop released: arm idle where it stopped");
            self.output
                .events
                .push(ArmNodeEvent::EmergencyStop { engaged: false });
        }

        let (joints, joints_stamp_ns) = match self.last_joints {
            Some((q, _, stamp)) => (JointPosition::from_array(q), stamp),
            None => (JointPosition::from_array([f64::NAN; 4]), 0),
        };
        let (valve_open, apple_attached) = self.vacuum_view(input.vacuum);
        self.note_refusal(input.grant);
        let other_arm = input.other_arm.map(|o| (self.other_arm_view(&o), o.state));
        let offer = self.offer(now_ns, other_arm.as_ref().map(|o| o.1));
        let cycle_input = CycleInput {
            now_ns,
            joints,
            joints_stamp_ns,
            valve_open,
            apple_attached,
            target: offer,
            other_arm: if self.config.other_arm_present {
                other_arm.map(|o| o.0)
            } else {
                None
            },
        };
        let out = self.cycle.step(&cycle_input);
        if let Some(decision) = &out.target_decision {
            self.on_decision(decision);
        }
        if let Some(event) = out.event {
            self.on_cycle_event(event);
        }
        self.set_phase(reported_phase(out.phase));
        self.set_valve(match out.valve_request {
            CycleValve::Open => ValveRequestKind::OpenForAttach,
            CycleValve::Closed => ValveRequestKind::Close,
        });
        let manual = self.manual.as_ref().map(|motion| motion.setpoint(now_ns));
        let servo = if let Some(manual) = manual {
            if manual.finished {
                debug!(arm = %self.arm, "manual move finished");
                self.manual = None;
            }
            self.setpoint = Some(manual.position);
            self.last_rate = manual.velocity;
            ServoOrder::Track {
                position: manual.position,
                velocity: manual.velocity,
            }
        } else if out.command.stopped {
            self.setpoint = None;
            ServoOrder::Hold
        } else {
            self.track(&joints, &out.command.velocity, dt_s)
        };
        self.output.servo = servo;
        self.output.goal_m = out.goal_m;
        self.fill_state(out.end_effector_m, apple_attached, period_ns);
        trace!(arm = %self.arm, phase = ?self.phase, ?servo, "arm node tick");
        &self.output
    }

    /// Records a new sample of the target channel as the pending target.
    fn take_new_target(&mut self, target: Option<&ArmTarget>) {
        let Some(target) = target else {
            return;
        };
        if target.arm_id != self.arm.number() || self.last_target_seq == Some(target.header.msg_seq)
        {
            return;
        }
        self.last_target_seq = Some(target.header.msg_seq);
        if target.apple_id == 0 {
            // Withdrawal: the supervisor handed the apple elsewhere.
            if let Some(p) = self.pending.take() {
                debug!(arm = %self.arm, apple_id = p.apple_id, "pending target withdrawn");
            }
            self.target_status = (TargetStatus::None, 0);
            return;
        }
        if self.attempt.is_some_and(|a| a.apple_id == target.apple_id) {
            // A re-publication of the apple this arm is already picking.
            return;
        }
        let refresh = self.pending.is_some_and(|p| p.apple_id == target.apple_id);
        self.pending = Some(*target);
        if refresh {
            // The same apple re-published (fresher detection): keep the refusal history.
            return;
        }
        self.last_rejection = None;
        self.deferred = false;
        self.target_status = (TargetStatus::None, target.apple_id);
        debug!(arm = %self.arm, apple_id = target.apple_id, "target received");
        self.output.events.push(ArmNodeEvent::TargetReceived {
            apple_id: target.apple_id,
        });
    }

    /// The target to offer the cycle this tick, if any.
    fn offer(&mut self, now_ns: u64, other: Option<&ArmState>) -> Option<TargetRequest> {
        let target = self.pending?;
        if self.cycle.phase() != CyclePhase::Idle {
            return None;
        }
        if self.targets_held || self.manual.is_some() {
            // Reported as waiting: the vacuum supervisor hands the apple back after its
            // patience and dispatches nothing new while the operator holds the harvest.
            self.target_status = (TargetStatus::Waiting, target.apple_id);
            return None;
        }
        if self.config.other_arm_present {
            let fresh = other.is_some_and(|s| {
                now_ns.saturating_sub(s.header.capture_ns) as f64 * 1e-9
                    <= self.config.max_other_arm_age_s
            });
            if !fresh {
                self.target_status = (TargetStatus::Waiting, target.apple_id);
                if !self.deferred {
                    self.deferred = true;
                    warn!(arm = %self.arm, apple_id = target.apple_id,
                        "target deferred: other arm's state unknown");
                    self.output.events.push(ArmNodeEvent::TargetDeferred {
                        apple_id: target.apple_id,
                        reason: DeferReason::OtherArmUnknown,
                    });
                }
                return None;
            }
        }
        Some(TargetRequest {
            id: u64::from(target.apple_id),
            position_m: picking_point_m(
                target.position_in_robot_m,
                target.radius_m,
                self.config.contact_gap_m,
            ),
            detected_at_ns: target.source_capture_ns,
        })
    }

    fn on_decision(&mut self, decision: &TargetDecision) {
        let apple_id = self.pending.map_or(0, |t| t.apple_id);
        match decision {
            TargetDecision::Accepted { .. } => {
                self.pending = None;
                self.last_rejection = None;
                self.target_status = (TargetStatus::None, 0);
                self.attempt = Some(Attempt {
                    apple_id,
                    failure: None,
                    harvested: false,
                });
                self.output
                    .events
                    .push(ArmNodeEvent::TargetAccepted { apple_id });
            }
            TargetDecision::Rejected(reason) => {
                let will_retry = reason.is_retryable();
                if !will_retry {
                    self.pending = None;
                }
                let status = if will_retry {
                    TargetStatus::Waiting
                } else {
                    TargetStatus::Refused
                };
                self.target_status = (status, apple_id);
                let kind = std::mem::discriminant(reason);
                if self.last_rejection != Some(kind) || !will_retry {
                    self.last_rejection = Some(kind);
                    self.output.events.push(ArmNodeEvent::TargetRejected {
                        apple_id,
                        reason: reason.clone(),
                        will_retry,
                    });
                }
            }
        }
    }

    fn on_cycle_event(&mut self, event: CycleEvent) {
        self.output.events.push(ArmNodeEvent::Cycle(event));
        let Some(attempt) = self.attempt.as_mut() else {
            return;
        };
        if let Some(failure) = AttemptFailure::from_event(event) {
            attempt.failure.get_or_insert(failure);
        }
        if event == (CycleEvent::CycleComplete { harvested: true }) {
            attempt.harvested = true;
            self.harvested_count = self.harvested_count.saturating_add(1);
        }
    }

    /// Publishes a phase change; the end of a cycle (back to idle) ends the attempt.
    fn set_phase(&mut self, phase: PhaseCode) {
        if phase == self.phase {
            return;
        }
        let from = self.phase;
        self.phase = phase;
        self.output
            .events
            .push(ArmNodeEvent::PhaseChanged { from, to: phase });
        if matches!(phase, PhaseCode::Idle | PhaseCode::Stopped)
            && let Some(attempt) = self.attempt.take()
        {
            let failure = if attempt.harvested {
                None
            } else if phase == PhaseCode::Stopped {
                Some(AttemptFailure::EmergencyStop)
            } else {
                attempt.failure
            };
            debug!(arm = %self.arm, apple_id = attempt.apple_id, harvested = attempt.harvested,
                ?failure, "attempt ended");
            self.output.events.push(ArmNodeEvent::AttemptEnded {
                apple_id: attempt.apple_id,
                harvested: attempt.harvested,
                failure,
            });
        }
    }

    fn set_valve(&mut self, kind: ValveRequestKind) {
        if kind == self.valve_kind {
            return;
        }
        self.valve_kind = kind;
        self.request_seq = self.request_seq.wrapping_add(1);
        self.output.valve_request.kind.set(kind);
        self.output.valve_request.request_seq = self.request_seq;
        self.output.events.push(ArmNodeEvent::ValveRequested {
            kind,
            request_seq: self.request_seq,
        });
    }

    /// Reports a refusal of the current request once per reason.
    fn note_refusal(&mut self, grant: Option<&ValveGrant>) {
        let Some(grant) = grant else {
            return;
        };
        if grant.arm_id != self.arm.number()
            || grant.granted != 0
            || grant.request_seq != self.request_seq
            || self.last_refusal == Some((grant.request_seq, grant.reason))
        {
            return;
        }
        self.last_refusal = Some((grant.request_seq, grant.reason));
        self.output.events.push(ArmNodeEvent::ValveRefused {
            reason_code: grant.reason,
        });
    }

    /// `(valve open, apple attached)` as the picking cycle must see them (module docs).
    fn vacuum_view(&self, vacuum: Option<&VacuumState>) -> (bool, bool) {
        let Some(v) = vacuum else {
            return (false, false);
        };
        let inlet = inlet_index(self.arm);
        let vent = inlet + 1;
        let settled = v.valve_in_transit[inlet] == 0 && v.valve_in_transit[vent] == 0;
        let commanded_open = v.valve_open[inlet] == 1 && v.valve_open[vent] == 0;
        let index = self.arm.index();
        let vented = v.pressure_mmh2o[index] < self.config.vented_vacuum_mmh2o;
        let valve_open = if commanded_open {
            settled
        } else {
            !(settled && vented)
        };
        (valve_open, v.arm_attachment[index] == ArmAttachment::Sealed)
    }

    /// Integrates the rate command into the position set-point (module docs).
    fn track(&mut self, joints: &JointPosition, rate: &JointVelocity, dt_s: f64) -> ServoOrder {
        let q = joints.to_array();
        let lo = self.params.position_limits.min.to_array();
        let hi = self.params.position_limits.max.to_array();
        let mut setpoint = match self.setpoint {
            Some(mut sp) => {
                for (j, value) in sp.iter_mut().enumerate() {
                    *value += self.last_rate[j] * dt_s;
                }
                let diverged = (0..4).any(|j| {
                    let limit = if j == 0 {
                        self.config.setpoint_resync_m
                    } else {
                        self.config.setpoint_resync_rad
                    };
                    (sp[j] - q[j]).abs() > limit
                });
                if diverged {
                    debug!(arm = %self.arm, ?sp, ?q, "set-point resynchronised to the encoders");
                    q
                } else {
                    sp
                }
            }
            None => q,
        };
        for j in 0..4 {
            setpoint[j] = setpoint[j].clamp(lo[j], hi[j]);
        }
        let velocity = rate.to_array();
        self.setpoint = Some(setpoint);
        self.last_rate = velocity;
        ServoOrder::Track {
            position: setpoint,
            velocity,
        }
    }

    fn emergency_stop(&mut self, period_ns: u64) {
        self.manual = None;
        if !self.stopped {
            self.stopped = true;
            warn!(arm = %self.arm, phase = ?self.phase, "emergency stop: braking, valve closed");
            self.output
                .events
                .push(ArmNodeEvent::EmergencyStop { engaged: true });
            // Abandon the cycle: a fresh one starts idle where the arm stops.
            if let Ok(cycle) = PickingCycle::new(self.params, self.other_params, self.config.cycle)
            {
                self.cycle = cycle;
            }
        }
        // Targets received while stopped are dropped: the supervisor dispatches again.
        self.pending = None;
        self.target_status = (TargetStatus::None, 0);
        self.setpoint = None;
        self.last_rate = [0.0; 4];
        self.set_phase(PhaseCode::Stopped);
        self.set_valve(ValveRequestKind::Close);
        self.output.servo = ServoOrder::Hold;
        self.output.goal_m = None;
        let ee = self.last_joints.map_or([f64::NAN; 3], |(q, _, _)| {
            forward(&self.params.links, &JointPosition::from_array(q))
        });
        self.fill_state(ee, false, period_ns);
    }

    fn fill_state(&mut self, end_effector_m: [f64; 3], holding: bool, period_ns: u64) {
        self.state_seq += 1;
        let (position, velocity, capture_ns) =
            self.last_joints
                .unwrap_or(([f64::NAN; 4], [f64::NAN; 4], 0));
        let apple_id = match self.attempt {
            Some(a) => a.apple_id,
            None => 0,
        };
        self.output.state = ArmState {
            header: Header {
                msg_seq: self.state_seq,
                capture_ns,
                publish_ns: 0,
            },
            arm_id: self.arm.number(),
            phase: self.phase.into(),
            holding: u8::from(holding),
            target_status: self.target_status.0.into(),
            target_apple_id: match self.target_status.0 {
                TargetStatus::None => 0,
                _ => self.target_status.1,
            },
            apple_id,
            harvested_count: self.harvested_count,
            joint_position: position,
            joint_velocity: velocity,
            end_effector_in_robot_m: end_effector_m,
            control_period_ns: period_ns,
        };
    }
}

#[cfg(test)]
mod tests;
