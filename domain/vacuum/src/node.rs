//! The vacuum supervisor's logic without any transport: [`VacuumNode`] owns the four valves of
//! the shared vacuum (paper 003, section 2.3), infers each arm's attachment from the three
//! pressure sensors, runs the coordination policy (section 3.3, eq. 7-12, or the 2023 / baseline
//! policies of section 4.2) and **assigns the apples to the arms**.
//!
//! Assignment lives in the vacuum process, next to the policy, because dispatching a target is
//! the policy's `StartApproach` decision (eq. 8, first clause: an arm may leave the drop-off only
//! with an apple assigned; the baseline lets one arm out at a time). Each detection set is fed to
//! an [`AssignmentPlanner`] (Algorithm 1 plus re-planning); when an arm is idle with apples in its
//! queue and the policy grants `StartApproach`, the head of its queue is published on the arm's
//! target channel. The node learns how the attempt went from the arm's `ArmState` (phase back to
//! idle; `harvested_count` up or not) and tells the planner, which retries a failed apple when a
//! later detection set still sees it. At most one target is dispatched per tick, so the arm that
//! moves second always sees the first arm's motion in its clearance check.
//!
//! An arm that refuses its target for the moment (its path would come too close to the other
//! arm's: `ArmState::target_status` waiting) keeps retrying it; once it has waited
//! [`VacuumNodeConfig::waiting_patience_s`], the node takes the apple back without counting an
//! attempt and hands it to the other arm (head of its queue) when that arm can reach it, or to
//! the back of the same arm's queue when that arm has other apples to do first; the arm gets
//! its next apple, or a withdrawal (a target with apple id 0). A target refused for good
//! (`target_status` refused) ends the attempt as failed at once, as the dispatch timeout would.
//!
//! Per tick ([`VacuumNode::step`]):
//! 1. the pressure sample goes through [`AttachmentInference`]; an arm counts as open for the
//!    inference only once the board reports its inlet at the open end stop and its vent closed
//!    (a gate takes up to a second to travel, section 2.3);
//! 2. a new detection set re-plans the assignment;
//! 3. attempts are tracked from the arms' states;
//! 4. the policy's force-closes are applied (failure, release, out of workflow);
//! 5. the arms' standing valve requests are answered: `Close` always, `OpenForAttach` once per
//!    request (a request the policy closed again is not re-opened), oldest waiter first; whatever
//!    the policy and whatever the arms report, a valve never opens beside the other arm's open
//!    valve unless this node's own inference reads that cup sealed (the safety monitor's
//!    opened-beside-unsealed rule, kept here as an interlock: arm states are outside data);
//! 6. the policy is asked again for force-closes; then the interlock's second rule: when both
//!    valves are open with neither cup sealed (the safety monitor's both-open-unsealed rule), the
//!    failed one is closed (attach failed, apple dropped), or the later opened when none failed,
//!    whatever the policy (the baseline never closes a failure on its own);
//! 7. at most one target is dispatched.
//!
//! Emergency stop: every valve is commanded closed at once (`close_all`), open requests are
//! refused, nothing is dispatched, and the attempts in progress are given up as failed.
//!
//! Pure logic: no clock reads, no I/O; the caller passes the time, the board readings and the
//! received messages, and applies the outputs.

use crate::assignment::{Apple, AppleId};
use crate::policy::{
    ArmStatus, CloseReason, Decision, PairStatus, PolicyKind, RefuseReason, Request, VacuumPolicy,
    ValveOrder, new_policy,
};
use crate::pressure::{
    AttachmentChange, AttachmentInference, AttachmentState, PressureConfig, PressureConfigError,
    PressureSample, PressureSampleError,
};
use crate::replan::{
    AssignmentPlanner, AttemptResult, PlannerConfig, PlannerConfigError, ReplanSummary,
};
use harvest_ipc::Header;
use harvest_ipc::payloads::arm::TargetStatus;
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase as PhaseCode, ArmState, ArmTarget, VacuumState, ValveGrant,
    ValveRequest, ValveRequestKind,
};
use harvest_robot_model::arm_id::ArmId;
use harvest_robot_model::coordination_phase::CoordinationPhase;
use serde::{Deserialize, Serialize};
use thiserror::Error;
use tracing::{debug, info, trace, warn};

/// Refusal code sent in `ValveGrant::reason` while the emergency stop is engaged.
pub const REFUSED_EMERGENCY_STOP: u8 = 20;
/// Refusal code for an arm that does not take part (single-arm operation).
pub const REFUSED_ARM_DISABLED: u8 = 21;
/// Radius used when a detection carries none, m.
const FALLBACK_RADIUS_M: f64 = 0.04;

/// The wire code of a policy refusal (`ValveGrant::reason`; 0 = none).
pub fn refuse_reason_code(reason: &RefuseReason) -> u8 {
    match reason {
        RefuseReason::NotReady { .. } => 1,
        RefuseReason::NoAppleAssigned => 2,
        RefuseReason::NotAtApple { .. } => 3,
        RefuseReason::ValveAlreadyOpen => 4,
        RefuseReason::OtherArmAttempting => 5,
        RefuseReason::OtherArmFailing => 6,
        RefuseReason::VacuumHeldByOther { .. } => 7,
        RefuseReason::OtherArmActive { .. } => 8,
    }
}

/// The policy code of `VacuumState::policy` (0 baseline, 1 2023, 2 2024).
pub fn policy_code(kind: PolicyKind) -> u8 {
    match kind {
        PolicyKind::Baseline => 0,
        PolicyKind::V2023 => 1,
        PolicyKind::V2024 => 2,
    }
}

/// The attachment code of `VacuumState::arm_attachment` (0 closed, 1 open, 2 sealed; a latched
/// failure is open and unsealed).
pub fn attachment_code(state: AttachmentState) -> u8 {
    match state {
        AttachmentState::Closed => 0,
        AttachmentState::Sealed => 2,
        AttachmentState::OpenToAtmosphere
        | AttachmentState::AttachFailed
        | AttachmentState::Dropped => 1,
    }
}

/// Settings of the node.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VacuumNodeConfig {
    /// Coordination policy.
    pub policy: PolicyKind,
    /// Attachment inference thresholds.
    pub pressure: PressureConfig,
    /// Assignment and re-planning.
    pub planner: PlannerConfig,
    /// Arms that take part, indexed by [`ArmId::index`] (single-arm operation: `[true,
    /// false]`). A disabled arm gets no apple and its valve stays closed.
    pub arms_enabled: [bool; 2],
    /// A dispatched target that its arm has not taken up after this long is given up as a
    /// failed attempt, s (default 3 s: longer than the arm's 2 s target age limit, so the arm
    /// has dropped it by then).
    pub dispatch_timeout_s: f64,
    /// Radius of the give-up list, m (default 0.05 m: below the 7-8 cm between the centres of
    /// two touching apples, above the 3 cm identity match of the planner). A detection within
    /// it of a spot where `planner.max_attempts` attempts were made is ignored, so an apple
    /// that perception re-identifies as new after each attempt, or that the robot wrongly
    /// believes harvested, is not tried forever.
    pub give_up_radius_m: f64,
    /// Margin around an apple held in a cup, m (default 0.03 m: the 1.5 cm from cup to apple
    /// surface within which the cup seals, section 2.2, plus the +-1.5 cm localization error
    /// the end-effector tolerates). A detection whose centre lies within its own radius plus
    /// this margin of the end-effector (`ArmState::end_effector_in_robot_m`) of an arm that
    /// holds an apple, retracts or releases is the apple in that cup seen again, not a tree
    /// apple, and is left out of the assignment (counted as `held` in the re-plan summary).
    /// Two touching apples of radius r lie at least ~2.2 r apart measured from the cup, so the
    /// default (r + 3 cm, 7 cm for r = 4 cm) does not hide a neighbour.
    pub held_margin_m: f64,
    /// How long an arm may report its dispatched target as waiting (refused for the moment)
    /// before the apple is handed elsewhere, s (default 0.25 s: the other arm's swept path
    /// rarely clears sooner than its next phase, and a shorter wait would bounce apples between
    /// the arms at every perception period).
    pub waiting_patience_s: f64,
    /// An apple withdrawn from an arm is not dispatched to that arm again for this long, s
    /// (default 1 s, about one phase of the other arm, whose path was in the way).
    pub withdrawal_backoff_s: f64,
}

impl Default for VacuumNodeConfig {
    fn default() -> Self {
        Self {
            policy: PolicyKind::V2024,
            pressure: PressureConfig::default(),
            planner: PlannerConfig::default(),
            arms_enabled: [true, true],
            dispatch_timeout_s: 3.0,
            give_up_radius_m: 0.05,
            held_margin_m: 0.03,
            waiting_patience_s: 0.25,
            withdrawal_backoff_s: 1.0,
        }
    }
}

/// Why a [`VacuumNode`] could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VacuumNodeError {
    /// Invalid pressure thresholds.
    #[error("vacuum node: {0}")]
    Pressure(#[from] PressureConfigError),
    /// Invalid planner settings.
    #[error("vacuum node: {0}")]
    Planner(#[from] PlannerConfigError),
    /// `dispatch_timeout_s` is not a positive number of seconds.
    #[error("vacuum node config `dispatch_timeout_s` = {0}: must be finite and > 0")]
    DispatchTimeout(f64),
    /// `give_up_radius_m` is not a positive distance.
    #[error("vacuum node config `give_up_radius_m` = {0}: must be finite and > 0")]
    GiveUpRadius(f64),
    /// `held_margin_m` is not a non-negative distance.
    #[error("vacuum node config `held_margin_m` = {0}: must be finite and >= 0")]
    HeldMargin(f64),
    /// `waiting_patience_s` is not a non-negative number of seconds.
    #[error("vacuum node config `waiting_patience_s` = {0}: must be finite and >= 0")]
    WaitingPatience(f64),
    /// `withdrawal_backoff_s` is not a non-negative number of seconds.
    #[error("vacuum node config `withdrawal_backoff_s` = {0}: must be finite and >= 0")]
    WithdrawalBackoff(f64),
}

/// One report of the valve board (the `ValveBoard::valve_states` and `pressures` of a tick).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BoardReadings {
    /// When the board was read, ns.
    pub stamp_ns: u64,
    /// Position each valve 1-4 was last commanded to, as the board reports it.
    pub valve_open: [bool; 4],
    /// True while a gate has not reached that position yet.
    pub valve_in_transit: [bool; 4],
    /// Vacuum inside arm 1, inside arm 2 and at the source, mmH2O.
    pub pressure_mmh2o: [f32; 3],
}

/// Reachability of an apple by an arm: `(arm, apple centre in the robot frame m, radius m)`.
/// Supplied by the caller from the arm kinematics (inverse of eq. 1 within Table 1's limits).
pub type Reachability = Box<dyn Fn(ArmId, &[f64; 3], f64) -> bool + Send>;

/// One tick's inputs.
#[derive(Debug, Clone, Copy, Default)]
pub struct VacuumNodeInput<'a> {
    /// Now, ns (stack clock).
    pub now_ns: u64,
    /// Each arm's latest state, indexed by [`ArmId::index`].
    pub arm_states: [Option<&'a ArmState>; 2],
    /// Each arm's latest (standing) valve request.
    pub valve_requests: [Option<&'a ValveRequest>; 2],
    /// This tick's board readings, if read.
    pub readings: Option<BoardReadings>,
    /// A detection set received this tick.
    pub detections: Option<&'a AppleDetections>,
    /// True while the emergency stop is engaged.
    pub emergency_stop: bool,
}

/// Why a valve was closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ValveCloseCause {
    /// The arm asked (release at the drop-off, or it gave up the attempt).
    ArmRequest,
    /// The policy ordered it.
    Policy(CloseReason),
    /// Emergency stop.
    EmergencyStop,
    /// The interlock: both valves were open with neither cup sealed (module docs, step 6).
    Interlock,
}

/// Something the node did or saw this tick.
#[derive(Debug, Clone, PartialEq)]
pub enum VacuumNodeEvent {
    /// A detection set re-planned the assignment.
    Replanned {
        /// What changed.
        summary: ReplanSummary,
        /// Queue lengths after it, per arm.
        queued: [usize; 2],
        /// Detections dropped for a non-finite position.
        invalid: usize,
        /// Detections ignored because they lie on the give-up list.
        given_up: usize,
    },
    /// A dispatched target not taken up yet was published again with the capture time of a
    /// detection set that still sees the apple (so it does not go stale while its arm waits
    /// for the other arm's path to clear).
    TargetRefreshed {
        /// The arm.
        arm: ArmId,
        /// The target.
        target: ArmTarget,
    },
    /// The planner refused a detection set (nothing changed).
    ReplanFailed {
        /// The planner's message.
        message: String,
    },
    /// A target was published for an arm.
    TargetDispatched {
        /// The arm.
        arm: ArmId,
        /// The target.
        target: ArmTarget,
    },
    /// The policy kept an idle arm with apples at the drop-off (reported once per reason).
    ApproachRefused {
        /// The arm.
        arm: ArmId,
        /// Why.
        reason: RefuseReason,
    },
    /// The arm took up its target.
    AttemptStarted {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
    },
    /// The arm did not take up its target in time; counted as a failed attempt.
    DispatchTimedOut {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
    },
    /// The arm refused its target for good (outside its workspace, stale, not finite);
    /// counted as a failed attempt.
    TargetRefused {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
    },
    /// The arm kept refusing its target for the moment (the other arm in the way): the apple
    /// was taken back, not counted as an attempt, and queued for `to`.
    TargetWithdrawn {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
        /// The arm whose queue it joined (the other arm at its head, or the same arm at its
        /// back).
        to: ArmId,
    },
    /// An attempt ended (the arm is idle again).
    AttemptFinished {
        /// The arm.
        arm: ArmId,
        /// The apple.
        apple: AppleId,
        /// Harvested or failed.
        result: AttemptResult,
    },
    /// An arm's valve was opened on its request.
    ValveOpened {
        /// The arm.
        arm: ArmId,
    },
    /// An arm's open request was refused (reported once per request and reason).
    ValveRefused {
        /// The arm.
        arm: ArmId,
        /// Why (`None`: emergency stop or disabled arm).
        reason: Option<RefuseReason>,
    },
    /// An arm's valve was closed.
    ValveClosed {
        /// The arm.
        arm: ArmId,
        /// Why.
        cause: ValveCloseCause,
    },
    /// The attachment inference of an arm changed.
    Attachment(AttachmentChange),
    /// A pressure sample was refused (state unchanged).
    SampleRefused(PressureSampleError),
    /// The emergency stop was engaged (true) or released (false).
    EmergencyStop {
        /// New state.
        engaged: bool,
    },
}

/// One tick's outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct VacuumNodeOutput {
    /// Commanded position of valves 1-4 (true = open); apply the ones that changed.
    pub valve_commands: [bool; 4],
    /// True on the tick the emergency stop engaged: use the board's `close_all`.
    pub close_all: bool,
    /// Answers to publish on `vacuum/valve_grant`, per arm.
    pub grants: [Option<ValveGrant>; 2],
    /// Targets to publish on `arm1/target` / `arm2/target`.
    pub targets: [Option<ArmTarget>; 2],
    /// The state to publish on `vacuum/state`.
    pub state: VacuumState,
    /// What happened.
    pub events: Vec<VacuumNodeEvent>,
}

/// A target handed to an arm.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Dispatch {
    apple: Apple,
    at_ns: u64,
    harvested_before: u32,
}

/// An apple taken back from an arm that kept waiting for the other arm.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Withdrawal {
    apple: AppleId,
    position_m: [f64; 3],
    at_ns: u64,
    /// Handed to the other arm (which can reach it): while the back-off lasts, the assignment
    /// treats it as out of this arm's reach, so re-planning does not hand it straight back.
    to_other: bool,
}

/// What the node tracks per arm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct ArmTrack {
    /// Commanded: source valve open (valve 1 or 3 open, 2 or 4 closed).
    valve_open: bool,
    /// When the valve was last opened, ns.
    opened_at_ns: u64,
    /// Dispatched, not yet taken up.
    dispatched: Option<Dispatch>,
    /// Taken up, running.
    active: Option<Dispatch>,
    /// The valve was granted during the current attempt.
    opened_in_cycle: bool,
    /// Request sequence of the last open granted (never granted twice).
    granted_seq: Option<u32>,
    /// Last refusal reported: (request seq, code).
    refused: Option<(u32, u8)>,
    /// Standing open request first seen at, ns (oldest waiter served first).
    open_request_since_ns: Option<(u32, u64)>,
    /// Last approach refusal reported.
    approach_refusal: Option<u8>,
    /// Last dispatch time, ns (dispatch fairness).
    last_dispatch_ns: u64,
    /// The last target published for this arm.
    last_target: Option<ArmTarget>,
    /// The apple last withdrawn from this arm (adopted if the arm took it up regardless; not
    /// dispatched to it again within `withdrawal_backoff_s`).
    withdrawn: Option<Withdrawal>,
}

/// The vacuum supervisor's logic; see the module documentation.
pub struct VacuumNode {
    config: VacuumNodeConfig,
    policy: Box<dyn VacuumPolicy + Send + Sync>,
    inference: AttachmentInference,
    planner: AssignmentPlanner,
    reachable: Reachability,
    arms: [ArmTrack; 2],
    /// Latest detection set: (centre, radius) and its capture time.
    last_set: Vec<([f64; 3], f64)>,
    last_set_capture_ns: u64,
    scratch_positions: Vec<[f64; 3]>,
    /// Where attempts were made, and how many (the give-up list).
    attempt_spots: Vec<([f64; 3], u32)>,
    stopped: bool,
    target_seq: u64,
    state_seq: u64,
    grant_seq: u64,
    last_readings: Option<BoardReadings>,
    output: VacuumNodeOutput,
}

impl std::fmt::Debug for VacuumNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VacuumNode")
            .field("config", &self.config)
            .field("arms", &self.arms)
            .field("stopped", &self.stopped)
            .finish_non_exhaustive()
    }
}

/// The policy's view of an arm's phase from its published state. A missing or stopped arm is
/// treated as away from the drop-off (it may be anywhere).
fn policy_phase(state: Option<&ArmState>, track: &ArmTrack) -> CoordinationPhase {
    if track.dispatched.is_some() {
        return CoordinationPhase::Approaching;
    }
    match state.and_then(|s| PhaseCode::from_code(s.phase)) {
        Some(PhaseCode::Idle) => CoordinationPhase::Ready,
        Some(PhaseCode::Approach) => CoordinationPhase::Approaching,
        Some(PhaseCode::AttachDetach) if track.valve_open => CoordinationPhase::Attaching,
        // Closed again after the valve was granted: the attempt is over, the arm returns.
        Some(PhaseCode::AttachDetach) if track.opened_in_cycle => CoordinationPhase::Retracting,
        Some(PhaseCode::AttachDetach) => CoordinationPhase::AtApple,
        Some(PhaseCode::Retract) => CoordinationPhase::Retracting,
        Some(PhaseCode::Release) => CoordinationPhase::Releasing,
        Some(PhaseCode::Stopped) | None => CoordinationPhase::Approaching,
    }
}

impl VacuumNode {
    /// A node with both valves closed and nothing assigned. `reachable` tells whether an arm
    /// can reach an apple (see [`Reachability`]).
    pub fn new(config: VacuumNodeConfig, reachable: Reachability) -> Result<Self, VacuumNodeError> {
        config.pressure.validate()?;
        if !(config.dispatch_timeout_s.is_finite() && config.dispatch_timeout_s > 0.0) {
            return Err(VacuumNodeError::DispatchTimeout(config.dispatch_timeout_s));
        }
        if !(config.give_up_radius_m.is_finite() && config.give_up_radius_m > 0.0) {
            return Err(VacuumNodeError::GiveUpRadius(config.give_up_radius_m));
        }
        if !(config.held_margin_m.is_finite() && config.held_margin_m >= 0.0) {
            return Err(VacuumNodeError::HeldMargin(config.held_margin_m));
        }
        if !(config.waiting_patience_s.is_finite() && config.waiting_patience_s >= 0.0) {
            return Err(VacuumNodeError::WaitingPatience(config.waiting_patience_s));
        }
        if !(config.withdrawal_backoff_s.is_finite() && config.withdrawal_backoff_s >= 0.0) {
            return Err(VacuumNodeError::WithdrawalBackoff(
                config.withdrawal_backoff_s,
            ));
        }
        let planner = AssignmentPlanner::new(config.planner)?;
        Ok(Self {
            policy: new_policy(config.policy),
            inference: AttachmentInference::new(config.pressure),
            planner,
            reachable,
            arms: [ArmTrack::default(); 2],
            last_set: Vec::new(),
            last_set_capture_ns: 0,
            scratch_positions: Vec::new(),
            attempt_spots: Vec::new(),
            stopped: false,
            target_seq: 0,
            state_seq: 0,
            grant_seq: 0,
            last_readings: None,
            output: VacuumNodeOutput {
                valve_commands: [false, true, false, true],
                close_all: false,
                grants: [None; 2],
                targets: [None; 2],
                state: VacuumState::default(),
                events: Vec::with_capacity(8),
            },
            config,
        })
    }

    /// The node's settings.
    pub fn config(&self) -> &VacuumNodeConfig {
        &self.config
    }

    /// The assignment planner (queues, attempts).
    pub fn planner(&self) -> &AssignmentPlanner {
        &self.planner
    }

    /// The inferred attachment of `arm`.
    pub fn attachment(&self, arm: ArmId) -> AttachmentState {
        self.inference.state(arm)
    }

    /// True when nothing is assigned, dispatched or running: no further target will be
    /// dispatched until a detection set brings new apples.
    pub fn is_idle(&self) -> bool {
        ArmId::ALL.iter().all(|&arm| {
            let track = &self.arms[arm.index()];
            track.dispatched.is_none()
                && track.active.is_none()
                && self.planner.in_progress(arm).is_none()
                && (!self.config.arms_enabled[arm.index()] || self.planner.queue(arm).is_empty())
        })
    }

    /// One tick; see the module documentation. The outputs stay valid until the next call.
    pub fn step(&mut self, input: &VacuumNodeInput<'_>) -> &VacuumNodeOutput {
        self.output.events.clear();
        self.output.grants = [None; 2];
        self.output.targets = [None; 2];
        self.output.close_all = false;
        let now_ns = input.now_ns;
        if let Some(readings) = input.readings {
            self.infer(&readings);
            self.last_readings = Some(readings);
        }
        if let Some(set) = input.detections {
            self.replan(set, &input.arm_states, now_ns);
        }
        self.track_attempts(input, now_ns);
        if input.emergency_stop {
            self.emergency_stop();
        } else {
            if self.stopped {
                self.stopped = false;
                info!("emergency stop released: vacuum supervisor resumes");
                self.output
                    .events
                    .push(VacuumNodeEvent::EmergencyStop { engaged: false });
            }
            self.supervise(input);
            self.answer_requests(input, now_ns);
            self.supervise(input);
            self.interlock();
            self.dispatch(input, now_ns);
        }
        self.output.valve_commands = [
            self.arms[0].valve_open,
            !self.arms[0].valve_open && !self.stopped,
            self.arms[1].valve_open,
            !self.arms[1].valve_open && !self.stopped,
        ];
        self.fill_state(now_ns);
        &self.output
    }

    /// Step 1: the pressure sample through the inference.
    fn infer(&mut self, readings: &BoardReadings) {
        let settled_open = ArmId::ALL.map(|arm| {
            let inlet = 2 * arm.index();
            let vent = inlet + 1;
            self.arms[arm.index()].valve_open
                && readings.valve_open[inlet]
                && !readings.valve_in_transit[inlet]
                && !readings.valve_open[vent]
                && !readings.valve_in_transit[vent]
        });
        let sample = PressureSample {
            stamp_ns: readings.stamp_ns,
            arm_vacuum_mmh2o: [readings.pressure_mmh2o[0], readings.pressure_mmh2o[1]],
            source_vacuum_mmh2o: readings.pressure_mmh2o[2],
        };
        match self.inference.update(&sample, settled_open) {
            Ok(changes) => {
                for change in changes.into_iter().flatten() {
                    self.output.events.push(VacuumNodeEvent::Attachment(change));
                }
            }
            Err(error) => {
                warn!(%error, "pressure sample refused");
                self.output
                    .events
                    .push(VacuumNodeEvent::SampleRefused(error));
            }
        }
    }

    /// Step 2: a new detection set. Detections of an apple held in a cup (see
    /// [`VacuumNodeConfig::held_margin_m`]) are left out before planning.
    fn replan(&mut self, set: &AppleDetections, arm_states: &[Option<&ArmState>; 2], now_ns: u64) {
        self.last_set.clear();
        self.scratch_positions.clear();
        let cups = arm_states.map(|s| s.and_then(holding_cup_m));
        let mut invalid = 0;
        let mut given_up = 0;
        let mut held = 0;
        for d in set.apples.iter() {
            let p = d.position_in_robot_m;
            if self.given_up(&p) {
                given_up += 1;
            } else if p.iter().all(|c| c.is_finite()) {
                let radius = if d.radius_m.is_finite() && d.radius_m > 0.0 {
                    d.radius_m
                } else {
                    FALLBACK_RADIUS_M
                };
                let reach_m = radius + self.config.held_margin_m;
                if cups
                    .iter()
                    .flatten()
                    .any(|cup| squared_distance(cup, &p) <= reach_m * reach_m)
                {
                    trace!(position_m = ?p, "detection at a holding arm's cup: not a tree apple");
                    held += 1;
                    continue;
                }
                self.last_set.push((p, radius));
                self.scratch_positions.push(p);
            } else {
                invalid += 1;
            }
        }
        self.last_set_capture_ns = set.source_capture_ns;
        let assignable = assignable(
            &self.config,
            &self.last_set,
            &self.reachable,
            self.avoided(now_ns),
        );
        let result = self.planner.replan(&self.scratch_positions, assignable);
        match result {
            Ok(mut summary) => {
                summary.held = held;
                let queued = ArmId::ALL.map(|arm| self.planner.queue(arm).len());
                trace!(?summary, ?queued, "re-planned");
                self.output.events.push(VacuumNodeEvent::Replanned {
                    summary,
                    queued,
                    invalid,
                    given_up,
                });
                self.refresh_dispatched();
            }
            Err(error) => {
                warn!(%error, "detection set refused by the planner");
                self.output.events.push(VacuumNodeEvent::ReplanFailed {
                    message: error.to_string(),
                });
            }
        }
    }

    /// Step 3: follow each arm's attempt from its published state.
    fn track_attempts(&mut self, input: &VacuumNodeInput<'_>, now_ns: u64) {
        let timeout_ns = (self.config.dispatch_timeout_s * 1e9) as u64;
        for arm in ArmId::ALL {
            let i = arm.index();
            let state = input.arm_states[i];
            let phase = state.and_then(|s| PhaseCode::from_code(s.phase));
            if matches!(phase, Some(PhaseCode::Idle | PhaseCode::Approach)) {
                self.arms[i].opened_in_cycle = false;
            }
            if let Some(d) = self.arms[i].dispatched {
                let taken = state.is_some_and(|s| {
                    s.apple_id == wire_id(d.apple.id) && phase.is_some_and(|p| p != PhaseCode::Idle)
                });
                if taken {
                    self.arms[i].dispatched = None;
                    self.arms[i].withdrawn = None;
                    self.arms[i].active = Some(d);
                    debug!(%arm, apple = d.apple.id.0, "attempt started");
                    self.output.events.push(VacuumNodeEvent::AttemptStarted {
                        arm,
                        apple: d.apple.id,
                    });
                } else {
                    if let Some(status) = state
                        .filter(|s| s.target_apple_id == wire_id(d.apple.id))
                        .and_then(|s| TargetStatus::from_code(s.target_status))
                        && status != TargetStatus::None
                    {
                        self.on_target_status(arm, d, status, now_ns);
                    }
                    // Still dispatched (waiting with nowhere else to go, or no report).
                    let still = self.arms[i].dispatched.is_some();
                    if still && now_ns.saturating_sub(d.at_ns) > timeout_ns {
                        self.arms[i].dispatched = None;
                        self.planner.finish(arm, AttemptResult::Failed);
                        self.remember(&d.apple.position_m);
                        warn!(%arm, apple = d.apple.id.0, "target not taken up: given up");
                        self.output.events.push(VacuumNodeEvent::DispatchTimedOut {
                            arm,
                            apple: d.apple.id,
                        });
                    }
                }
            }
            if self.arms[i].active.is_none()
                && let Some(Withdrawal { apple: id, .. }) = self.arms[i].withdrawn
                && let Some(s) = state
                && s.apple_id == wire_id(id)
                && phase.is_some_and(|p| p != PhaseCode::Idle && p != PhaseCode::Stopped)
            {
                self.adopt(arm, id, s, now_ns);
            }
            if let Some(d) = self.arms[i].active {
                let over = state.is_none_or(|s| {
                    s.apple_id != wire_id(d.apple.id) || phase == Some(PhaseCode::Idle)
                });
                if over {
                    let harvested = state.is_some_and(|s| s.harvested_count > d.harvested_before);
                    let result = if harvested {
                        AttemptResult::Harvested
                    } else {
                        AttemptResult::Failed
                    };
                    self.arms[i].active = None;
                    self.planner.finish(arm, result);
                    self.remember(&d.apple.position_m);
                    debug!(%arm, apple = d.apple.id.0, ?result, "attempt finished");
                    self.output.events.push(VacuumNodeEvent::AttemptFinished {
                        arm,
                        apple: d.apple.id,
                        result,
                    });
                }
            }
        }
    }

    /// A dispatched target the arm reports refused (for good, or for the moment).
    fn on_target_status(&mut self, arm: ArmId, d: Dispatch, status: TargetStatus, now_ns: u64) {
        let i = arm.index();
        if status == TargetStatus::Refused {
            self.arms[i].dispatched = None;
            self.planner.finish(arm, AttemptResult::Failed);
            self.remember(&d.apple.position_m);
            warn!(%arm, apple = d.apple.id.0, "target refused by the arm");
            self.output.events.push(VacuumNodeEvent::TargetRefused {
                arm,
                apple: d.apple.id,
            });
            return;
        }
        let patience_ns = (self.config.waiting_patience_s * 1e9) as u64;
        if now_ns.saturating_sub(d.at_ns) < patience_ns {
            return;
        }
        let other = arm.other();
        let radius_m = self.radius_of(&d.apple.position_m);
        let to = if self.config.arms_enabled[other.index()]
            && (self.reachable)(other, &d.apple.position_m, radius_m)
        {
            other
        } else if !self.planner.queue(arm).is_empty() {
            arm
        } else {
            // Nowhere else to go: the arm keeps retrying until it can go or the dispatch
            // times out.
            return;
        };
        if self.planner.take_back(arm, to).is_none() {
            return;
        }
        let track = &mut self.arms[i];
        track.dispatched = None;
        track.withdrawn = Some(Withdrawal {
            apple: d.apple.id,
            position_m: d.apple.position_m,
            at_ns: now_ns,
            to_other: to == other,
        });
        track.last_target = None;
        // Overwritten by the arm's next apple if one is dispatched this tick.
        self.output.targets[i] = Some(self.withdrawal_target(i, now_ns));
        debug!(%arm, apple = d.apple.id.0, %to, "target withdrawn: the arm waits for the other arm");
        self.output.events.push(VacuumNodeEvent::TargetWithdrawn {
            arm,
            apple: d.apple.id,
            to,
        });
    }

    /// The next target for arm `i` that withdraws the one it has not taken up (apple id 0, NaN
    /// position: an arm without withdrawals rejects it as not finite, with the same effect).
    fn withdrawal_target(&mut self, i: usize, now_ns: u64) -> ArmTarget {
        self.target_seq += 1;
        ArmTarget {
            header: Header {
                msg_seq: self.target_seq,
                capture_ns: now_ns,
                publish_ns: 0,
            },
            arm_id: i as u8 + 1,
            _reserved: [0; 3],
            apple_id: 0,
            position_in_robot_m: [f64::NAN; 3],
            radius_m: f64::NAN,
            source_capture_ns: self.last_set_capture_ns,
        }
    }

    /// The arm took up the apple withdrawn from it (the withdrawal crossed its acceptance):
    /// follow that attempt; a target dispatched since is taken back to the arm's own queue
    /// and withdrawn.
    fn adopt(&mut self, arm: ArmId, id: AppleId, state: &ArmState, now_ns: u64) {
        let i = arm.index();
        self.arms[i].withdrawn = None;
        if self.arms[i].dispatched.take().is_some() {
            self.planner.take_back(arm, arm);
            self.output.targets[i] = Some(self.withdrawal_target(i, now_ns));
        }
        let Some(apple) = self.planner.adopt(arm, id) else {
            warn!(%arm, apple = id.0, "arm took up a withdrawn apple that is no longer waiting");
            return;
        };
        self.arms[i].active = Some(Dispatch {
            apple,
            at_ns: now_ns,
            harvested_before: state.harvested_count,
        });
        info!(%arm, apple = id.0, "arm took up a withdrawn target: attempt followed");
        self.output
            .events
            .push(VacuumNodeEvent::AttemptStarted { arm, apple: id });
    }

    /// Per arm, the position of the apple handed from it to the other arm while the back-off
    /// lasts (treated as out of its reach by the assignment).
    fn avoided(&self, now_ns: u64) -> [Option<[f64; 3]>; 2] {
        let backoff_ns = (self.config.withdrawal_backoff_s * 1e9) as u64;
        self.arms.map(|track| {
            track
                .withdrawn
                .filter(|w| w.to_other && now_ns.saturating_sub(w.at_ns) < backoff_ns)
                .map(|w| w.position_m)
        })
    }

    /// The radius of the detection at `position_m` in the last set.
    fn radius_of(&self, position_m: &[f64; 3]) -> f64 {
        radius_in(&self.last_set, position_m)
    }

    /// True when `position_m` lies on the give-up list.
    fn given_up(&self, position_m: &[f64; 3]) -> bool {
        let r2 = self.config.give_up_radius_m.powi(2);
        let limit = self.config.planner.max_attempts;
        self.attempt_spots
            .iter()
            .any(|(p, attempts)| *attempts >= limit && squared_distance(p, position_m) <= r2)
    }

    /// Counts an attempt at `position_m` on the give-up list, whatever its result: it joins
    /// the nearest spot within the give-up radius (whose position becomes the mean of its
    /// attempts' targets, averaging the localization noise out) or starts a new one. A
    /// harvested apple is gone from later detection sets, so its spot never masks anything;
    /// an apple the robot only believes harvested (it slipped off unnoticed and sprang back
    /// to its stem) is seen again at the same spot and stops being tried after
    /// `max_attempts`.
    fn remember(&mut self, position_m: &[f64; 3]) {
        let r2 = self.config.give_up_radius_m.powi(2);
        let nearest = self
            .attempt_spots
            .iter_mut()
            .map(|spot| (squared_distance(&spot.0, position_m), spot))
            .filter(|(d2, _)| *d2 <= r2)
            .min_by(|a, b| a.0.total_cmp(&b.0));
        match nearest {
            Some((_, (p, attempts))) => {
                let n = f64::from(*attempts);
                for (c, new) in p.iter_mut().zip(position_m) {
                    *c = (*c * n + new) / (n + 1.0);
                }
                *attempts += 1;
            }
            None => self.attempt_spots.push((*position_m, 1)),
        }
    }

    /// Re-publishes the targets dispatched but not taken up yet when the new set still sees
    /// their apple (within the planner's match radius).
    fn refresh_dispatched(&mut self) {
        let r2 = self.config.planner.match_radius_m.powi(2);
        for arm in ArmId::ALL {
            let i = arm.index();
            let Some(d) = self.arms[i].dispatched else {
                continue;
            };
            let seen = self
                .last_set
                .iter()
                .any(|(p, _)| squared_distance(p, &d.apple.position_m) <= r2);
            if !seen {
                continue;
            }
            let Some(mut target) = self.output.targets[i].or(self.arms[i].last_target) else {
                continue;
            };
            self.target_seq += 1;
            target.header.msg_seq = self.target_seq;
            target.source_capture_ns = self.last_set_capture_ns;
            self.arms[i].last_target = Some(target);
            self.output.targets[i] = Some(target);
            trace!(%arm, apple = d.apple.id.0, "dispatched target refreshed");
            self.output
                .events
                .push(VacuumNodeEvent::TargetRefreshed { arm, target });
        }
    }

    fn emergency_stop(&mut self) {
        if !self.stopped {
            self.stopped = true;
            self.output.close_all = true;
            warn!("emergency stop: closing every valve");
            self.output
                .events
                .push(VacuumNodeEvent::EmergencyStop { engaged: true });
            for arm in ArmId::ALL {
                let track = &mut self.arms[arm.index()];
                if track.valve_open {
                    track.valve_open = false;
                    self.output.events.push(VacuumNodeEvent::ValveClosed {
                        arm,
                        cause: ValveCloseCause::EmergencyStop,
                    });
                }
                let apple = track.dispatched.take().or(track.active.take());
                if let Some(d) = apple {
                    self.planner.finish(arm, AttemptResult::Failed);
                    self.output.events.push(VacuumNodeEvent::AttemptFinished {
                        arm,
                        apple: d.apple.id,
                        result: AttemptResult::Failed,
                    });
                }
            }
        }
    }

    /// Step 6, the interlock's second rule (module docs): both valves open, neither cup sealed.
    fn interlock(&mut self) {
        let unsealed_open = |node: &Self, arm: ArmId| {
            node.arms[arm.index()].valve_open
                && node.inference.state(arm) != AttachmentState::Sealed
        };
        if !ArmId::ALL.iter().all(|&arm| unsealed_open(self, arm)) {
            return;
        }
        let failed = ArmId::ALL.map(|arm| {
            matches!(
                self.inference.state(arm),
                AttachmentState::AttachFailed | AttachmentState::Dropped
            )
        });
        let close = if failed.iter().any(|&f| f) {
            failed
        } else if self.arms[1].opened_at_ns >= self.arms[0].opened_at_ns {
            [false, true]
        } else {
            [true, false]
        };
        for arm in ArmId::ALL {
            if close[arm.index()] {
                self.arms[arm.index()].valve_open = false;
                warn!(%arm, "interlock: both valves open with neither cup sealed; valve closed");
                self.output.events.push(VacuumNodeEvent::ValveClosed {
                    arm,
                    cause: ValveCloseCause::Interlock,
                });
            }
        }
    }

    fn pair(&self, input: &VacuumNodeInput<'_>) -> PairStatus {
        PairStatus(ArmId::ALL.map(|arm| {
            let i = arm.index();
            let track = &self.arms[i];
            ArmStatus {
                phase: policy_phase(input.arm_states[i], track),
                valve_open: track.valve_open,
                attachment: self.inference.state(arm),
                apple_assigned: self.config.arms_enabled[i]
                    && (track.dispatched.is_some() || !self.planner.queue(arm).is_empty()),
            }
        }))
    }

    /// Steps 4 and 6: the policy's force-closes.
    fn supervise(&mut self, input: &VacuumNodeInput<'_>) {
        let orders = self.policy.supervise(&self.pair(input));
        for arm in ArmId::ALL {
            if let ValveOrder::ForceClose(reason) = orders[arm.index()]
                && self.arms[arm.index()].valve_open
            {
                self.arms[arm.index()].valve_open = false;
                debug!(%arm, %reason, "valve force-closed by the policy");
                self.output.events.push(VacuumNodeEvent::ValveClosed {
                    arm,
                    cause: ValveCloseCause::Policy(reason),
                });
            }
        }
    }

    /// Step 5: the arms' standing valve requests.
    fn answer_requests(&mut self, input: &VacuumNodeInput<'_>, now_ns: u64) {
        let mut order = ArmId::ALL;
        for arm in ArmId::ALL {
            let track = &mut self.arms[arm.index()];
            match input.valve_requests[arm.index()] {
                Some(r) if r.kind == ValveRequestKind::OpenForAttach as u8 => {
                    if track.open_request_since_ns.map(|(seq, _)| seq) != Some(r.request_seq) {
                        track.open_request_since_ns = Some((r.request_seq, now_ns));
                    }
                }
                _ => track.open_request_since_ns = None,
            }
        }
        let since = |track: &ArmTrack| track.open_request_since_ns.map_or(u64::MAX, |(_, t)| t);
        if since(&self.arms[1]) < since(&self.arms[0]) {
            order = [ArmId::Arm2, ArmId::Arm1];
        }
        for arm in order {
            let i = arm.index();
            let Some(request) = input.valve_requests[i] else {
                continue;
            };
            if request.arm_id != arm.index() as u8 + 1 {
                continue;
            }
            match ValveRequestKind::from_code(request.kind) {
                Some(ValveRequestKind::Close) | None => {
                    if self.arms[i].valve_open {
                        self.arms[i].valve_open = false;
                        debug!(%arm, "valve closed on the arm's request");
                        self.output.events.push(VacuumNodeEvent::ValveClosed {
                            arm,
                            cause: ValveCloseCause::ArmRequest,
                        });
                    }
                }
                Some(ValveRequestKind::OpenForAttach) => self.answer_open(input, arm, request),
            }
        }
    }

    fn answer_open(&mut self, input: &VacuumNodeInput<'_>, arm: ArmId, request: &ValveRequest) {
        let i = arm.index();
        let track = self.arms[i];
        if track.valve_open || track.granted_seq == Some(request.request_seq) {
            return;
        }
        let other = arm.other();
        // The interlock (module docs): only this node's valves and pressures, no arm report.
        let beside_unsealed = self.arms[other.index()].valve_open
            && self.inference.state(other) != AttachmentState::Sealed;
        let (code, reason) = if !self.config.arms_enabled[i] {
            (REFUSED_ARM_DISABLED, None)
        } else if beside_unsealed {
            let reason = RefuseReason::OtherArmAttempting;
            (refuse_reason_code(&reason), Some(reason))
        } else {
            match self
                .policy
                .decide(arm, Request::OpenValve, &self.pair(input))
            {
                Decision::Grant => {
                    let track = &mut self.arms[i];
                    track.valve_open = true;
                    track.opened_at_ns = input.now_ns;
                    track.opened_in_cycle = true;
                    track.granted_seq = Some(request.request_seq);
                    track.refused = None;
                    debug!(%arm, request_seq = request.request_seq, "valve opened");
                    self.output
                        .events
                        .push(VacuumNodeEvent::ValveOpened { arm });
                    self.output.grants[i] = Some(self.grant(input.now_ns, arm, request, 0));
                    return;
                }
                Decision::Refuse(reason) => (refuse_reason_code(&reason), Some(reason)),
            }
        };
        if self.arms[i].refused != Some((request.request_seq, code)) {
            self.arms[i].refused = Some((request.request_seq, code));
            debug!(%arm, code, ?reason, "valve request refused");
            self.output
                .events
                .push(VacuumNodeEvent::ValveRefused { arm, reason });
            self.output.grants[i] = Some(self.grant(input.now_ns, arm, request, code));
        }
    }

    fn grant(&mut self, now_ns: u64, arm: ArmId, request: &ValveRequest, code: u8) -> ValveGrant {
        self.grant_seq += 1;
        ValveGrant {
            header: Header {
                msg_seq: self.grant_seq,
                capture_ns: now_ns,
                publish_ns: 0,
            },
            arm_id: arm.index() as u8 + 1,
            granted: u8::from(code == 0),
            reason: code,
            _reserved: 0,
            request_seq: request.request_seq,
        }
    }

    /// Step 7: at most one target per tick, to the idle arm that got one least recently.
    fn dispatch(&mut self, input: &VacuumNodeInput<'_>, now_ns: u64) {
        let mut order = ArmId::ALL;
        if self.arms[1].last_dispatch_ns < self.arms[0].last_dispatch_ns {
            order = [ArmId::Arm2, ArmId::Arm1];
        }
        for arm in order {
            let i = arm.index();
            let Some(state) = input.arm_states[i] else {
                continue;
            };
            let track = self.arms[i];
            let idle = state.phase == PhaseCode::Idle as u8
                && track.dispatched.is_none()
                && track.active.is_none()
                && self.planner.in_progress(arm).is_none();
            if self.config.arms_enabled[i] && idle && self.planner.queue(arm).is_empty() {
                self.rebalance_for(arm, now_ns);
            }
            if !self.config.arms_enabled[i] || !idle || self.planner.queue(arm).is_empty() {
                continue;
            }
            let backoff_ns = (self.config.withdrawal_backoff_s * 1e9) as u64;
            if let Some(w) = self.arms[i].withdrawn
                && now_ns.saturating_sub(w.at_ns) < backoff_ns
                && self
                    .planner
                    .queue(arm)
                    .first()
                    .is_some_and(|a| a.id == w.apple)
            {
                continue;
            }
            match self
                .policy
                .decide(arm, Request::StartApproach, &self.pair(input))
            {
                Decision::Grant => {
                    let Some(apple) = self.planner.start_next(arm) else {
                        continue;
                    };
                    let radius_m = self.radius_of(&apple.position_m);
                    self.target_seq += 1;
                    let target = ArmTarget {
                        header: Header {
                            msg_seq: self.target_seq,
                            capture_ns: now_ns,
                            publish_ns: 0,
                        },
                        arm_id: i as u8 + 1,
                        _reserved: [0; 3],
                        apple_id: wire_id(apple.id),
                        position_in_robot_m: apple.position_m,
                        radius_m,
                        source_capture_ns: self.last_set_capture_ns,
                    };
                    let track = &mut self.arms[i];
                    track.dispatched = Some(Dispatch {
                        apple,
                        at_ns: now_ns,
                        harvested_before: state.harvested_count,
                    });
                    track.last_dispatch_ns = now_ns;
                    track.last_target = Some(target);
                    track.approach_refusal = None;
                    debug!(%arm, apple = apple.id.0, position_m = ?apple.position_m,
                        "target dispatched");
                    self.output.targets[i] = Some(target);
                    self.output
                        .events
                        .push(VacuumNodeEvent::TargetDispatched { arm, target });
                    return;
                }
                Decision::Refuse(reason) => {
                    let code = refuse_reason_code(&reason);
                    if self.arms[i].approach_refusal != Some(code) {
                        self.arms[i].approach_refusal = Some(code);
                        self.output
                            .events
                            .push(VacuumNodeEvent::ApproachRefused { arm, reason });
                    }
                }
            }
        }
    }

    /// Gives the free `arm` its share of the apples queued for the other arm at once (see
    /// [`AssignmentPlanner::rebalance_for`]) instead of at the next detection set.
    fn rebalance_for(&mut self, arm: ArmId, now_ns: u64) {
        let assignable = assignable(
            &self.config,
            &self.last_set,
            &self.reachable,
            self.avoided(now_ns),
        );
        let result = self.planner.rebalance_for(arm, assignable);
        match result {
            Ok(true) => debug!(%arm, queued = self.planner.queue(arm).len(), "queues rebalanced"),
            Ok(false) => {}
            Err(error) => warn!(%error, "rebalancing refused by the planner"),
        }
    }

    fn fill_state(&mut self, now_ns: u64) {
        self.state_seq += 1;
        let readings = self.last_readings.unwrap_or_default();
        self.output.state = VacuumState {
            header: Header {
                msg_seq: self.state_seq,
                capture_ns: if self.last_readings.is_some() {
                    readings.stamp_ns
                } else {
                    now_ns
                },
                publish_ns: 0,
            },
            valve_open: readings.valve_open.map(u8::from),
            valve_in_transit: readings.valve_in_transit.map(u8::from),
            pressure_mmh2o: readings.pressure_mmh2o,
            arm_attachment: ArmId::ALL.map(|arm| attachment_code(self.inference.state(arm))),
            policy: policy_code(self.config.policy),
            _reserved: 0,
        };
    }
}

/// The apple id on the wire (`ArmTarget::apple_id`, `ArmState::apple_id`): the planner's id
/// plus one, so that 0 keeps meaning "no apple".
pub fn wire_id(id: AppleId) -> u32 {
    id.0.wrapping_add(1)
}

/// The cup of an arm whose end-effector carries (or may carry) an apple away from the tree:
/// it holds one (`ArmState::holding`), or it retracts or releases. `None` otherwise, or when
/// the end-effector position is not finite.
fn holding_cup_m(state: &ArmState) -> Option<[f64; 3]> {
    let carrying = state.holding != 0
        || matches!(
            PhaseCode::from_code(state.phase),
            Some(PhaseCode::Retract | PhaseCode::Release)
        );
    let cup = state.end_effector_in_robot_m;
    (carrying && cup.iter().all(|c| c.is_finite())).then_some(cup)
}

/// The assignment's test whether `arm` may be given the apple at `p`: the arm takes part, it
/// reaches the apple (with the apple's radius in the last detection set), and it is not backing
/// off from that spot (`avoid`: per arm, see [`VacuumNode::avoided`]).
fn assignable<'a>(
    config: &VacuumNodeConfig,
    last_set: &'a [([f64; 3], f64)],
    reachable: &'a Reachability,
    avoid: [Option<[f64; 3]>; 2],
) -> impl Fn(ArmId, &[f64; 3]) -> bool + 'a {
    let enabled = config.arms_enabled;
    let r2 = config.planner.match_radius_m.powi(2);
    move |arm, p| {
        enabled[arm.index()]
            && reachable(arm, p, radius_in(last_set, p))
            && !avoid[arm.index()].is_some_and(|q| squared_distance(&q, p) <= r2)
    }
}

/// The radius of the detection at `position_m` in `last_set` (a detection set's positions and
/// radii); [`FALLBACK_RADIUS_M`] when it is not there.
fn radius_in(last_set: &[([f64; 3], f64)], position_m: &[f64; 3]) -> f64 {
    last_set
        .iter()
        .find(|(p, _)| p == position_m)
        .map_or(FALLBACK_RADIUS_M, |(_, r)| *r)
}

fn squared_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]).powi(2)).sum()
}

#[cfg(test)]
mod tests;
