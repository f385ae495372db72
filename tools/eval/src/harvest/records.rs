//! What one episode produced: a time-stamped event log attributed to apples, one record per
//! attempt and per apple, and the classification of failed attempts by what the ground truth
//! says happened (Table 3's vacuum-side causes: sealing, detachment, interference).

use std::collections::BTreeMap;

use harvest_arm::node::{ArmNodeEvent, AttemptFailure};
use harvest_ipc::payloads::{ArmPhase as PhaseCode, ArmTarget};
use harvest_sim::orchard::{Apple, AppleState, World};

use crate::laser::refinement::distance;
use harvest_sim::physics::{DropCause, ReleaseOutcome, WorldEvent};
use harvest_vacuum::node::{VacuumNodeEvent, ValveCloseCause};
use serde::Serialize;

/// Radius around a target within which the nearest true apple is recorded, m.
pub const NEAR_APPLE_M: f64 = 0.15;
/// A target within this distance of an apple on the tree aimed at it (the attempt's `apple`), m.
pub const TARGET_MATCH_M: f64 = 0.05;

/// Why an attempt did not harvest its apple, judged from the simulator's ground truth first
/// and the arm's own report second.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureCause {
    /// A leaf between cup and fruit prevented the seal (Table 3 "Sealing").
    Sealing,
    /// The stem held harder than the cup; the fruit slipped off (Table 3 "Detachment").
    Detachment,
    /// A branch knocked the fruit off during the retract (Table 3 "Interference").
    Interference,
    /// The fruit fell because the vacuum sagged with the valve open.
    LowVacuum,
    /// The fruit was released away from the dropping module.
    ReleasedOffModule,
    /// The cup let go of a fruit still on its stem.
    ReleasedOnTree,
    /// No seal and no leaf: the cup never came within the seal distance (localization or
    /// approach error).
    MissedApple,
    /// The arm did not settle at the apple.
    ApproachTimeout,
    /// The vacuum supervisor did not open the valve in time.
    ValveNotGranted,
    /// The arm never took the target up (refused or timed out).
    TargetNotTaken,
    /// The emergency stop ended the attempt.
    EmergencyStop,
    /// Anything else.
    Other,
}

/// One entry of an episode's event log (what the report prints and writes to JSON): when, which
/// arm and true apple, and a description of what happened (an arm node, vacuum node or world
/// event). Not the `harvest/events` payload `harvest_ipc::payloads::HarvestEvent`, which the
/// stack's processes publish with typed codes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EpisodeLogEntry {
    /// Simulated time since the episode started, s.
    pub t_s: f64,
    /// Arm number (1 or 2), if the event concerns an arm.
    pub arm: Option<u8>,
    /// True apple id (simulator), if the event concerns one.
    pub apple: Option<u32>,
    /// What happened.
    pub what: String,
}

/// One phase of an attempt.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PhaseSpan {
    /// The phase (`ArmPhase` of the arm's state).
    pub phase: String,
    /// When it began, s.
    pub start_s: f64,
}

/// One attempt: a target dispatched to an arm, until the arm is idle again.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AttemptRecord {
    /// Arm number.
    pub arm: u8,
    /// The vacuum supervisor's apple id.
    pub planner_apple: u32,
    /// The true apple the target was closest to, and the target's centre error, m.
    pub apple: Option<u32>,
    /// Distance between the target centre and the true centre at dispatch, m.
    pub target_error_m: Option<f64>,
    /// The true apple on the tree nearest the target within [`NEAR_APPLE_M`] (also when the
    /// target matched none within 5 cm): whose flags (exposure, occlusion, cluster) a
    /// mislocalized target is attributed to.
    pub near_apple: Option<u32>,
    /// Dispatch time, s.
    pub dispatched_s: f64,
    /// When the arm accepted it, s.
    pub started_s: Option<f64>,
    /// When the arm was idle again (or the dispatch was given up), s.
    pub ended_s: Option<f64>,
    /// Phases in order.
    pub phases: Vec<PhaseSpan>,
    /// The arm released an apple at the drop-off and the simulator put it on the module.
    pub harvested: bool,
    /// Why not.
    pub cause: Option<FailureCause>,
    /// The arm's own account of the failure.
    pub arm_failure: Option<AttemptFailure>,
    /// Ground-truth events during the attempt (this arm's cup).
    pub world: Vec<String>,
    /// The true apple nearest the target at dispatch whatever its state (on the tree, in a
    /// cup, on the module or the ground): what a target that matched no apple on the tree was
    /// looking at.
    pub nearest_any: Option<NearestApple>,
    /// The forces when the fruit slipped off the cup (Table 3 "Detachment"), if it did.
    pub slip: Option<SlipForces>,
}

/// The true apple nearest a target, in any state.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NearestApple {
    pub apple: u32,
    /// Target to true centre, m.
    pub distance_m: f64,
    /// Its state then.
    pub state: AppleStateKind,
}

/// An apple's state without its details (serialized as its name).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum AppleStateKind {
    OnTree,
    Attached,
    Dropped,
    Harvested,
}

impl From<&AppleState> for AppleStateKind {
    fn from(state: &AppleState) -> Self {
        match state {
            AppleState::OnTree => Self::OnTree,
            AppleState::Attached { .. } => Self::Attached,
            AppleState::Dropped => Self::Dropped,
            AppleState::Harvested => Self::Harvested,
        }
    }
}

/// Stem tension and the cup's holding force when a fruit slipped off, N.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SlipForces {
    pub tension_n: f64,
    pub holding_force_n: f64,
}

impl AttemptRecord {
    /// Durations of the Approach, Attach/Detach, Retract and Release phases, s.
    pub fn phase_durations_s(&self) -> [Option<f64>; 4] {
        let mut out = [None; 4];
        for (k, span) in self.phases.iter().enumerate() {
            let end = self.phases.get(k + 1).map(|s| s.start_s).or(self.ended_s);
            let slot = match span.phase.as_str() {
                "Approach" => 0,
                "AttachDetach" => 1,
                "Retract" => 2,
                "Release" => 3,
                _ => continue,
            };
            if let Some(end) = end {
                *out[slot].get_or_insert(0.0) += end - span.start_s;
            }
        }
        out
    }
}

/// One true apple.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AppleRecord {
    /// True apple id.
    pub apple: u32,
    /// Attempts made on it.
    pub attempts: u32,
    /// It ended on the dropping module.
    pub harvested: bool,
    /// Its first attempt harvested it.
    pub first_attempt_success: bool,
    /// Its final state in the simulator.
    pub final_state: String,
}

/// Collects the log and the attempts of one episode.
#[derive(Debug, Clone, Default)]
pub struct Recorder {
    keep_events: bool,
    /// The event log (only when `keep_events`).
    pub events: Vec<EpisodeLogEntry>,
    /// Every attempt.
    pub attempts: Vec<AttemptRecord>,
    current: [Option<usize>; 2],
    last: [Option<usize>; 2],
    /// Times apples landed on the dropping module, s.
    pub releases_s: Vec<f64>,
}

impl Recorder {
    /// A recorder; `keep_events` keeps the full event log.
    pub fn new(keep_events: bool) -> Self {
        Self {
            keep_events,
            ..Self::default()
        }
    }

    fn log(&mut self, t_s: f64, arm: Option<u8>, what: String) {
        if !self.keep_events {
            return;
        }
        let apple = arm
            .and_then(|a| self.current[usize::from(a) - 1])
            .and_then(|i| self.attempts.get(i))
            .and_then(|r| r.apple);
        self.events.push(EpisodeLogEntry {
            t_s,
            arm,
            apple,
            what,
        });
    }

    /// A target was dispatched to `arm` (0-based index).
    pub fn on_dispatch(&mut self, t_s: f64, arm: usize, target: &ArmTarget, world: &World) {
        let distance_m =
            |apple: &Apple| distance(apple.center_in_robot_m, target.position_in_robot_m);
        let nearest = world
            .apples()
            .iter()
            .filter(|a| a.state == AppleState::OnTree)
            .map(|a| (a.id, distance_m(a)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let near = nearest
            .filter(|(_, d)| *d < NEAR_APPLE_M)
            .map(|(id, _)| id.0);
        let nearest = nearest.filter(|(_, d)| *d < TARGET_MATCH_M);
        let nearest_any = world
            .apples()
            .iter()
            .map(|a| (a, distance_m(a)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(a, d)| NearestApple {
                apple: a.id.0,
                distance_m: d,
                state: AppleStateKind::from(&a.state),
            });
        self.attempts.push(AttemptRecord {
            arm: arm as u8 + 1,
            planner_apple: target.apple_id,
            apple: nearest.map(|(id, _)| id.0),
            target_error_m: nearest.map(|(_, d)| d),
            near_apple: near,
            dispatched_s: t_s,
            started_s: None,
            ended_s: None,
            phases: Vec::new(),
            harvested: false,
            cause: None,
            arm_failure: None,
            world: Vec::new(),
            nearest_any,
            slip: None,
        });
        self.current[arm] = Some(self.attempts.len() - 1);
        self.last[arm] = self.current[arm];
        self.log(
            t_s,
            Some(arm as u8 + 1),
            format!(
                "assigned (planner apple {}, target error {:.1} mm)",
                target.apple_id,
                nearest.map_or(f64::NAN, |(_, d)| d * 1e3)
            ),
        );
    }

    /// An arm node event of `arm` (0-based).
    pub fn on_arm_event(&mut self, t_s: f64, arm: usize, event: &ArmNodeEvent) {
        let current = self.current[arm];
        match event {
            ArmNodeEvent::TargetAccepted { .. } => {
                if let Some(r) = current.and_then(|i| self.attempts.get_mut(i)) {
                    r.started_s = Some(t_s);
                }
            }
            ArmNodeEvent::PhaseChanged { to, .. } => {
                if let Some(r) = current.and_then(|i| self.attempts.get_mut(i))
                    && r.started_s.is_some()
                    && !matches!(to, PhaseCode::Idle)
                {
                    r.phases.push(PhaseSpan {
                        phase: format!("{to:?}"),
                        start_s: t_s,
                    });
                }
            }
            ArmNodeEvent::AttemptEnded {
                harvested, failure, ..
            } => {
                if let Some(r) = current.and_then(|i| self.attempts.get_mut(i)) {
                    r.ended_s = Some(t_s);
                    r.arm_failure = *failure;
                    // The arm believes it released an apple; the simulator decides whether it
                    // landed on the module (see `on_world_event`).
                    if !*harvested && !r.harvested && r.cause.is_none() {
                        r.cause = Some(classify(r, *failure));
                    }
                }
                self.current[arm] = None;
            }
            _ => {}
        }
        self.log(t_s, Some(arm as u8 + 1), format!("{event:?}"));
    }

    /// A vacuum node event.
    pub fn on_vacuum_event(&mut self, t_s: f64, event: &VacuumNodeEvent) {
        let arm = match event {
            VacuumNodeEvent::TargetWithdrawn { arm, .. } => {
                // Not an attempt: the arm never moved for it.
                let i = arm.index();
                if let Some(k) = self.current[i]
                    .filter(|&k| self.attempts.get(k).is_some_and(|r| r.started_s.is_none()))
                {
                    self.attempts.remove(k);
                    for slot in self.current.iter_mut().chain(self.last.iter_mut()) {
                        *slot = match *slot {
                            Some(x) if x == k => None,
                            Some(x) if x > k => Some(x - 1),
                            other => other,
                        };
                    }
                }
                Some(i as u8 + 1)
            }
            VacuumNodeEvent::DispatchTimedOut { arm, .. }
            | VacuumNodeEvent::TargetRefused { arm, .. } => {
                let i = arm.index();
                if let Some(r) = self.current[i].and_then(|k| self.attempts.get_mut(k)) {
                    r.ended_s = Some(t_s);
                    r.cause = Some(FailureCause::TargetNotTaken);
                }
                self.current[i] = None;
                Some(i as u8 + 1)
            }
            VacuumNodeEvent::ValveOpened { arm }
            | VacuumNodeEvent::ValveRefused { arm, .. }
            | VacuumNodeEvent::AttemptStarted { arm, .. }
            | VacuumNodeEvent::AttemptFinished { arm, .. }
            | VacuumNodeEvent::ApproachRefused { arm, .. } => Some(arm.index() as u8 + 1),
            VacuumNodeEvent::ValveClosed { arm, cause } => {
                if matches!(cause, ValveCloseCause::EmergencyStop)
                    && let Some(r) =
                        self.current[arm.index()].and_then(|k| self.attempts.get_mut(k))
                {
                    r.cause.get_or_insert(FailureCause::EmergencyStop);
                }
                Some(arm.index() as u8 + 1)
            }
            VacuumNodeEvent::Attachment(change) => Some(change.arm.index() as u8 + 1),
            VacuumNodeEvent::TargetDispatched { .. } => return,
            _ => None,
        };
        self.log(t_s, arm, format!("vacuum: {event:?}"));
    }

    /// A ground-truth event of the simulator.
    pub fn on_world_event(&mut self, t_s: f64, event: &WorldEvent) {
        let (arm, apple, what) = match *event {
            WorldEvent::SealBlocked { arm, apple } => (arm, apple, "seal blocked by a leaf"),
            WorldEvent::Attached { arm, apple } => (arm, apple, "attached"),
            WorldEvent::Detached { arm, apple } => (arm, apple, "detached from the stem"),
            WorldEvent::Slipped { arm, apple, .. } => (arm, apple, "slipped off the cup"),
            WorldEvent::Dropped { arm, apple, cause } => (
                arm,
                apple,
                match cause {
                    DropCause::HoldingInterference => "knocked off by a branch",
                    DropCause::LowVacuum => "dropped: low vacuum",
                },
            ),
            WorldEvent::Released {
                arm,
                apple,
                outcome,
            } => {
                if outcome == ReleaseOutcome::Harvested {
                    self.releases_s.push(t_s);
                }
                (
                    arm,
                    apple,
                    match outcome {
                        ReleaseOutcome::Harvested => "released onto the dropping module",
                        ReleaseOutcome::Dropped => "released off the module",
                        ReleaseOutcome::BackOnTree => "let go on the tree",
                    },
                )
            }
        };
        let i = arm.index();
        if let Some(r) = self.current[i]
            .or(self.last[i])
            .and_then(|k| self.attempts.get_mut(k))
        {
            r.world.push(format!("{what} (apple {})", apple.0));
            if let WorldEvent::Slipped {
                tension_n,
                holding_force_n,
                ..
            } = *event
            {
                r.slip = Some(SlipForces {
                    tension_n,
                    holding_force_n,
                });
            }
            if let WorldEvent::Released {
                outcome: ReleaseOutcome::Harvested,
                ..
            } = event
            {
                r.harvested = true;
                r.cause = None;
            }
        }
        self.log(
            t_s,
            Some(arm.number()),
            format!("world: apple {}: {what}", apple.0),
        );
    }

    /// Classifies every ended, failed attempt not classified yet (an apple that fell after its
    /// arm went idle is judged here); attempts cut by the end of the episode stay without a
    /// cause. Call once at the end of the episode.
    pub fn finalize(&mut self) {
        for r in &mut self.attempts {
            if !r.harvested && r.cause.is_none() && r.ended_s.is_some() {
                r.cause = Some(classify(r, r.arm_failure));
            }
        }
    }

    /// Per true apple, from the attempts and the final world.
    pub fn apples(&self, world: &World) -> Vec<AppleRecord> {
        let mut by_apple: BTreeMap<u32, Vec<&AttemptRecord>> = BTreeMap::new();
        for r in &self.attempts {
            if let Some(apple) = r.apple {
                by_apple.entry(apple).or_default().push(r);
            }
        }
        world
            .apples()
            .iter()
            .filter_map(|a| {
                let attempts = by_apple.get(&a.id.0)?;
                let harvested = a.state == AppleState::Harvested;
                Some(AppleRecord {
                    apple: a.id.0,
                    attempts: attempts.len() as u32,
                    harvested,
                    first_attempt_success: harvested
                        && attempts.first().is_some_and(|r| r.harvested),
                    final_state: format!("{:?}", a.state),
                })
            })
            .collect()
    }
}

/// The cause of a failed attempt: ground truth first, then the arm's report.
fn classify(record: &AttemptRecord, failure: Option<AttemptFailure>) -> FailureCause {
    let saw = |text: &str| record.world.iter().any(|w| w.starts_with(text));
    if failure == Some(AttemptFailure::EmergencyStop) {
        FailureCause::EmergencyStop
    } else if saw("seal blocked") {
        FailureCause::Sealing
    } else if saw("slipped") {
        FailureCause::Detachment
    } else if saw("knocked off") {
        FailureCause::Interference
    } else if saw("dropped: low vacuum") {
        FailureCause::LowVacuum
    } else if saw("released off") {
        FailureCause::ReleasedOffModule
    } else if saw("let go on the tree") {
        FailureCause::ReleasedOnTree
    } else {
        match failure {
            Some(AttemptFailure::ApproachTimeout) => FailureCause::ApproachTimeout,
            Some(AttemptFailure::ValveNotGranted) => FailureCause::ValveNotGranted,
            Some(AttemptFailure::NoAttachment) if !saw("attached") => FailureCause::MissedApple,
            _ => FailureCause::Other,
        }
    }
}
