//! The vacuum supervisor's logic without any transport: [`VacuumNode`] owns the four valves of
//! the shared vacuum ([dual-arm sec. 2.3]), infers each arm's attachment from the three
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
//! received messages, and applies the outputs. A tick allocates nothing once running (every
//! list is sized at construction and reused; `tests/step_allocations.rs` counts).
//!
//! Layout: the node's interface (`config`, `input`, `output`, `event`, `wire_codes`), what it
//! tracks per arm (`arm_track`) and how the policy sees the arms (`policy_view`), then one file
//! per part of the tick: `planning` (step 2), `attempts` (step 3), `valves` (steps 4-6, the
//! interlock and the emergency stop), `dispatch` (step 7). Step 1 (the pressure inference) and the published
//! state are in this file.

mod arm_track;
mod attempts;
mod config;
mod cup_trail;
mod dispatch;
mod event;
mod input;
mod output;
mod planning;
mod policy_view;
mod valves;
mod wire_codes;

pub use config::{VacuumNodeConfig, VacuumNodeError};
pub use event::{VacuumNodeEvent, ValveCloseCause};
pub use input::{BoardReadings, Reachability, VacuumNodeInput};
pub use output::VacuumNodeOutput;
pub use wire_codes::{
    REFUSED_ARM_DISABLED, REFUSED_EMERGENCY_STOP, attachment_code, policy_code, refuse_reason_code,
    wire_id,
};

use tracing::{info, warn};

use crate::policy::{VacuumPolicy, new_policy};
use crate::pressure::{AttachmentInference, AttachmentState, PressureSample};
use crate::replan::AssignmentPlanner;
use arm_track::ArmTrack;
use cup_trail::CupTrail;
use harvest_ipc::Header;
use harvest_ipc::payloads::VacuumState;
use harvest_ipc::payloads::apple_detections::MAX_APPLES_PER_FRAME;
use harvest_robot_model::ArmId;

/// Spots of attempted apples the give-up list has room for from the start (it keeps one per
/// apple attempted; beyond this it grows, one allocation per doubling).
const ATTEMPT_SPOTS_CAPACITY: usize = 1024;

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
    /// Per arm, where its cup carried an apple lately (detections captured then are that
    /// apple, not a tree apple).
    cup_trails: [CupTrail; 2],
    stopped: bool,
    target_seq: u64,
    state_seq: u64,
    grant_seq: u64,
    last_readings: Option<BoardReadings>,
    /// Per arm: no target is dispatched (operator: not harvesting, or the arm disabled).
    dispatch_held: [bool; 2],
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
        if !(config.slip_give_up_vacuum_mmh2o.is_finite()
            && config.slip_give_up_vacuum_mmh2o >= 0.0)
        {
            return Err(VacuumNodeError::SlipGiveUpVacuum(
                config.slip_give_up_vacuum_mmh2o,
            ));
        }
        let planner = AssignmentPlanner::new(config.planner)?;
        Ok(Self {
            policy: new_policy(config.policy),
            inference: AttachmentInference::new(config.pressure),
            planner,
            reachable,
            arms: [ArmTrack::default(); 2],
            last_set: Vec::with_capacity(MAX_APPLES_PER_FRAME),
            last_set_capture_ns: 0,
            scratch_positions: Vec::with_capacity(MAX_APPLES_PER_FRAME),
            attempt_spots: Vec::with_capacity(ATTEMPT_SPOTS_CAPACITY),
            cup_trails: [CupTrail::default(); 2],
            stopped: false,
            target_seq: 0,
            state_seq: 0,
            grant_seq: 0,
            last_readings: None,
            dispatch_held: [false; 2],
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

    /// Holds the dispatch of new targets per arm (indexed by [`ArmId::index`]): the operator
    /// paused or stopped the harvest, or disabled the arm. Attempts under way go on (their
    /// valve requests are answered as before); a dispatched target the arm holds back as
    /// waiting is taken back after [`VacuumNodeConfig::waiting_patience_s`].
    pub fn hold_dispatch(&mut self, held: [bool; 2]) {
        if held != self.dispatch_held {
            info!(?held, "dispatch of new targets held per arm");
        }
        self.dispatch_held = held;
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

    /// The outputs of the last [`Self::step`] (empty before the first).
    pub fn last_output(&self) -> &VacuumNodeOutput {
        &self.output
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
        self.record_cups(&input.arm_states, now_ns);
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
                    let track = &mut self.arms[change.arm.index()];
                    if change.from == AttachmentState::Sealed
                        && change.to == AttachmentState::Dropped
                    {
                        track.seal_lost_after_mmh2o = Some(track.sealed_peak_mmh2o);
                    }
                    self.output.events.push(VacuumNodeEvent::Attachment(change));
                }
                for arm in ArmId::ALL {
                    if self.inference.state(arm) == AttachmentState::Sealed {
                        let track = &mut self.arms[arm.index()];
                        track.sealed_peak_mmh2o = track
                            .sealed_peak_mmh2o
                            .max(sample.arm_vacuum_mmh2o[arm.index()]);
                    }
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
            arm_attachment: ArmId::ALL.map(|arm| attachment_code(self.inference.state(arm)).into()),
            policy: policy_code(self.config.policy).into(),
            _reserved: 0,
        };
    }
}

#[cfg(test)]
mod tests;
