//! Keeping the assignment current as detection sets arrive ([dual-arm sec. 3.3]: the arms
//! harvest continuously "whenever apples are available", and `Apple_Detected_i` may become true
//! at any time).
//!
//! On each new detection set the planner
//! - keeps every apple an arm is working on, seen or not (the arm is already committed);
//! - matches the other detections to the apples it knows, nearest first within
//!   `match_radius_m`, so an apple keeps its id (and its attempt count) across sets;
//! - drops known apples that are no longer seen, adds unmatched detections as new apples;
//! - skips apples already attempted `max_attempts` times;
//! - runs Algorithm 1 again over the waiting apples, counting the apples the arms are working on
//!   in each arm's half ([`crate::assignment::assign_apples_with_held`]).
//!
//! A failed apple is not put back in a queue at once: it waits for the next detection set,
//! which tells whether it is still on the tree and where.
//!
//! The planner runs inside the vacuum supervisor's 200 Hz tick, so re-planning allocates
//! nothing once running: every list is a vector reused from set to set (sized at construction
//! for [`PLANNED_APPLES`] apples; more only grow them once), sorts are in place.

use crate::assignment::{
    Apple, AppleId, AssignError, Assignment, AssignmentFrame, assign_apples_into,
};
use harvest_robot_model::ArmId;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use thiserror::Error;
use tracing::debug;

/// Apples the planner's lists have room for from the start: a detection set's maximum
/// ([`harvest_ipc::payloads::apple_detections::MAX_APPLES_PER_FRAME`]) plus the two in
/// progress and a set's worth of failed ones.
pub const PLANNED_APPLES: usize =
    2 * harvest_ipc::payloads::apple_detections::MAX_APPLES_PER_FRAME + 2;

/// Re-planning settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannerConfig {
    /// Two detections closer than this are the same apple, m. Default 0.03 m: twice the
    /// +-1.5 cm localization error the end-effector tolerates (section 2.2).
    pub match_radius_m: f64,
    /// Attempts per apple before it is left on the tree. Default 3 (Table 2 reports apples
    /// harvested on the first and on later attempts).
    pub max_attempts: u32,
    /// How positions are read.
    pub frame: AssignmentFrame,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        PlannerConfig {
            match_radius_m: 0.03,
            max_attempts: 3,
            frame: AssignmentFrame::ROBOT,
        }
    }
}

/// A [`PlannerConfig`] that cannot work.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum PlannerConfigError {
    /// `match_radius_m` is not a finite positive distance.
    #[error("planner config key `match_radius_m` = {0} m: must be finite and positive")]
    BadMatchRadius(f64),
    /// `max_attempts` is zero.
    #[error("planner config key `max_attempts` = 0: at least one attempt is needed")]
    ZeroAttempts,
}

/// What changed in one re-plan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReplanSummary {
    /// Known apples seen again.
    pub kept: usize,
    /// Known apples not seen any more (and not in progress).
    pub dropped: usize,
    /// Detections that matched no known apple.
    pub added: usize,
    /// Seen apples left out because they used all their attempts.
    pub exhausted: usize,
    /// Detections left out before planning because they are an apple held in an arm's cup
    /// (set by the vacuum node, see `VacuumNodeConfig::held_margin_m`; 0 from the planner).
    pub held: usize,
}

/// How an attempt ended, as reported by the arm workflow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AttemptResult {
    /// The apple was released on the drop-off ramp.
    Harvested,
    /// Failed attachment or drop: the apple may still be on the tree.
    Failed,
}

/// The assignment kept current across detection sets.
#[derive(Debug, Clone)]
pub struct AssignmentPlanner {
    config: PlannerConfig,
    next_id: u32,
    /// Apples of the last detection set that are not in progress (queued, unreachable or
    /// exhausted), plus apples whose attempt failed since.
    known: Vec<Apple>,
    attempts: HashMap<AppleId, u32>,
    in_progress: [Option<Apple>; 2],
    plan: Assignment,
    scratch: Scratch,
}

/// The re-plan's working lists, kept between sets so that re-planning does not allocate.
#[derive(Debug, Clone)]
struct Scratch {
    /// Matching candidates: `(apple, in progress)`.
    candidates: Vec<(Apple, bool)>,
    /// `(squared distance, detection, candidate)` within the match radius.
    pairs: Vec<(f64, usize, usize)>,
    detection_used: Vec<bool>,
    candidate_used: Vec<bool>,
    /// The known apples being built (swapped with `known` on success).
    next_known: Vec<Apple>,
    waiting: Vec<Apple>,
    /// The assignment being built (swapped with `plan` on success).
    next_plan: Assignment,
    shared: Vec<Apple>,
}

impl Scratch {
    fn with_capacity(apples: usize) -> Self {
        Self {
            candidates: Vec::with_capacity(apples),
            pairs: Vec::with_capacity(apples * 4),
            detection_used: Vec::with_capacity(apples),
            candidate_used: Vec::with_capacity(apples),
            next_known: Vec::with_capacity(apples),
            waiting: Vec::with_capacity(apples),
            next_plan: Assignment::with_capacity(apples),
            shared: Vec::with_capacity(apples),
        }
    }
}

impl AssignmentPlanner {
    /// An empty planner.
    pub fn new(config: PlannerConfig) -> Result<Self, PlannerConfigError> {
        if !(config.match_radius_m.is_finite() && config.match_radius_m > 0.0) {
            return Err(PlannerConfigError::BadMatchRadius(config.match_radius_m));
        }
        if config.max_attempts == 0 {
            return Err(PlannerConfigError::ZeroAttempts);
        }
        Ok(AssignmentPlanner {
            config,
            next_id: 0,
            known: Vec::with_capacity(PLANNED_APPLES),
            attempts: HashMap::with_capacity(PLANNED_APPLES),
            in_progress: [None, None],
            plan: Assignment::with_capacity(PLANNED_APPLES),
            scratch: Scratch::with_capacity(PLANNED_APPLES),
        })
    }

    /// Take a new detection set (positions in the assignment frame, m) and re-plan.
    /// `reachable(arm, position_m)` as in [`crate::assignment::assign_apples`]. On error nothing changes.
    pub fn replan<F>(
        &mut self,
        detections_m: &[[f64; 3]],
        reachable: F,
    ) -> Result<ReplanSummary, AssignError>
    where
        F: Fn(ArmId, &[f64; 3]) -> bool,
    {
        if let Some(bad) = detections_m
            .iter()
            .find(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(AssignError::NonFinitePosition {
                id: AppleId(self.next_id),
                position_m: *bad,
            });
        }
        // Candidates for matching: in-progress apples first (they absorb their own detection),
        // then the known ones.
        let scratch = &mut self.scratch;
        scratch.candidates.clear();
        scratch.candidates.extend(
            self.in_progress
                .iter()
                .flatten()
                .map(|a| (*a, true))
                .chain(self.known.iter().map(|a| (*a, false))),
        );
        let candidates = &scratch.candidates;
        let r2 = self.config.match_radius_m * self.config.match_radius_m;
        scratch.pairs.clear();
        for (di, d) in detections_m.iter().enumerate() {
            for (ci, (c, _)) in candidates.iter().enumerate() {
                let dist2 = squared_distance(d, &c.position_m);
                if dist2 <= r2 {
                    scratch.pairs.push((dist2, di, ci));
                }
            }
        }
        // (detection, candidate) pairs are unique: the order is total, in place is enough.
        scratch
            .pairs
            .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        scratch.detection_used.clear();
        scratch.detection_used.resize(detections_m.len(), false);
        scratch.candidate_used.clear();
        scratch.candidate_used.resize(candidates.len(), false);
        let detection_used = &mut scratch.detection_used;
        let candidate_used = &mut scratch.candidate_used;
        let next_known = &mut scratch.next_known;
        next_known.clear();
        let mut summary = ReplanSummary::default();
        for &(_, di, ci) in &scratch.pairs {
            if detection_used[di] || candidate_used[ci] {
                continue;
            }
            detection_used[di] = true;
            candidate_used[ci] = true;
            let (apple, in_progress) = candidates[ci];
            if !in_progress {
                next_known.push(Apple {
                    id: apple.id,
                    position_m: detections_m[di],
                });
                summary.kept += 1;
            }
        }
        summary.dropped = candidates
            .iter()
            .zip(candidate_used.iter())
            .filter(|((_, in_progress), used)| !*in_progress && !**used)
            .count();
        let mut next_id = self.next_id;
        for (di, used) in detection_used.iter().enumerate() {
            if !used {
                next_known.push(Apple {
                    id: AppleId(next_id),
                    position_m: detections_m[di],
                });
                next_id = next_id.wrapping_add(1);
                summary.added += 1;
            }
        }
        let attempts = &self.attempts;
        let max_attempts = self.config.max_attempts;
        scratch.waiting.clear();
        scratch.waiting.extend(
            next_known
                .iter()
                .filter(|a| attempts.get(&a.id).copied().unwrap_or(0) < max_attempts)
                .copied(),
        );
        summary.exhausted = next_known.len() - scratch.waiting.len();
        let held = self.in_progress.map(|a| usize::from(a.is_some()));
        assign_apples_into(
            &scratch.waiting,
            &self.config.frame,
            held,
            reachable,
            &mut scratch.next_plan,
            &mut scratch.shared,
        )?;
        self.next_id = next_id;
        std::mem::swap(&mut self.known, &mut scratch.next_known);
        std::mem::swap(&mut self.plan, &mut scratch.next_plan);
        self.attempts.retain(|id, _| {
            self.known.iter().any(|a| a.id == *id)
                || self.in_progress.iter().flatten().any(|a| a.id == *id)
        });
        debug!(
            kept = summary.kept,
            dropped = summary.dropped,
            added = summary.added,
            exhausted = summary.exhausted,
            arm1 = self.plan.arm1.len(),
            arm2 = self.plan.arm2.len(),
            "apple assignment re-planned"
        );
        Ok(summary)
    }

    /// Runs the split again over the apples already queued, without a new detection set, when
    /// `arm` is free with an empty queue while the other arm still has apples waiting: the
    /// queues were split while both arms were busy, and the free arm should not wait for the
    /// next set (up to one perception period) to take its share of the shared apples. Apples
    /// that failed stay out of the queues until a detection set sees them again, as in
    /// [`AssignmentPlanner::replan`]. Returns true when the queues changed.
    pub fn rebalance_for<F>(&mut self, arm: ArmId, reachable: F) -> Result<bool, AssignError>
    where
        F: Fn(ArmId, &[f64; 3]) -> bool,
    {
        if self.in_progress[arm.index()].is_some()
            || !self.plan.queue(arm).is_empty()
            || self.plan.queue(arm.other()).is_empty()
        {
            return Ok(false);
        }
        let scratch = &mut self.scratch;
        scratch.waiting.clear();
        scratch
            .waiting
            .extend(self.plan.arm1.iter().chain(&self.plan.arm2).copied());
        let held = self.in_progress.map(|a| usize::from(a.is_some()));
        assign_apples_into(
            &scratch.waiting,
            &self.config.frame,
            held,
            reachable,
            &mut scratch.next_plan,
            &mut scratch.shared,
        )?;
        scratch
            .next_plan
            .unreachable
            .extend_from_slice(&self.plan.unreachable);
        let changed = scratch.next_plan.queue(arm) != self.plan.queue(arm);
        std::mem::swap(&mut self.plan, &mut scratch.next_plan);
        Ok(changed)
    }

    /// The waiting queue of `arm`, next apple first.
    pub fn queue(&self, arm: ArmId) -> &[Apple] {
        self.plan.queue(arm)
    }

    /// Apples seen but reachable by neither arm.
    pub fn unreachable(&self) -> &[Apple] {
        &self.plan.unreachable
    }

    /// The apple `arm` is working on.
    pub fn in_progress(&self, arm: ArmId) -> Option<Apple> {
        self.in_progress[arm.index()]
    }

    /// Attempts started on `id` so far (while the planner still knows it).
    pub fn attempts(&self, id: AppleId) -> u32 {
        self.attempts.get(&id).copied().unwrap_or(0)
    }

    /// Start `arm` on the head of its queue: the apple moves to in-progress and its attempt
    /// count goes up. `None` if the queue is empty or the arm is still busy.
    pub fn start_next(&mut self, arm: ArmId) -> Option<Apple> {
        if self.in_progress[arm.index()].is_some() {
            return None;
        }
        let queue = match arm {
            ArmId::Arm1 => &mut self.plan.arm1,
            ArmId::Arm2 => &mut self.plan.arm2,
        };
        if queue.is_empty() {
            return None;
        }
        let apple = queue.remove(0);
        self.known.retain(|a| a.id != apple.id);
        *self.attempts.entry(apple.id).or_insert(0) += 1;
        self.in_progress[arm.index()] = Some(apple);
        Some(apple)
    }

    /// Takes back the apple `arm` was started on before the arm took it up (it refused the
    /// target for the moment, e.g. the other arm's swept path is in the way): its attempt is
    /// not counted, and it waits at the head of the queue of `to` (the other arm, which can
    /// reach it) or at the back of `arm`'s own queue (`to == arm`: the arm tries its other
    /// apples first). Returns the apple, `None` if the arm was idle.
    pub fn take_back(&mut self, arm: ArmId, to: ArmId) -> Option<Apple> {
        let apple = self.in_progress[arm.index()].take()?;
        if let Some(n) = self.attempts.get_mut(&apple.id) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                self.attempts.remove(&apple.id);
            }
        }
        let queue = match to {
            ArmId::Arm1 => &mut self.plan.arm1,
            ArmId::Arm2 => &mut self.plan.arm2,
        };
        if to == arm {
            queue.push(apple);
        } else {
            queue.insert(0, apple);
        }
        // Known again, so the next detection set matches it (same id).
        self.known.push(apple);
        Some(apple)
    }

    /// Starts `arm` on the waiting apple `id` (queued for either arm, or known), as
    /// [`AssignmentPlanner::start_next`] does for the head of its queue: used when an arm took
    /// up a target that was withdrawn from it. `None` (nothing changes) when the arm is busy or
    /// the apple is not waiting.
    pub fn adopt(&mut self, arm: ArmId, id: AppleId) -> Option<Apple> {
        if self.in_progress[arm.index()].is_some() {
            return None;
        }
        let apple = self
            .plan
            .arm1
            .iter()
            .chain(&self.plan.arm2)
            .chain(&self.known)
            .find(|a| a.id == id)
            .copied()?;
        self.plan.arm1.retain(|a| a.id != id);
        self.plan.arm2.retain(|a| a.id != id);
        self.known.retain(|a| a.id != id);
        *self.attempts.entry(id).or_insert(0) += 1;
        self.in_progress[arm.index()] = Some(apple);
        Some(apple)
    }

    /// End `arm`'s current attempt. A harvested apple is forgotten; a failed one is kept for
    /// matching with the next detection set. Returns the apple, `None` if the arm was idle.
    pub fn finish(&mut self, arm: ArmId, result: AttemptResult) -> Option<Apple> {
        let apple = self.in_progress[arm.index()].take()?;
        match result {
            AttemptResult::Harvested => {
                self.attempts.remove(&apple.id);
            }
            AttemptResult::Failed => self.known.push(apple),
        }
        Some(apple)
    }
}

fn squared_distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|i| (a[i] - b[i]) * (a[i] - b[i])).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Robot frame, arm 1 on +y: arm 1 reaches y >= -0.1, arm 2 y <= 0.1.
    fn reach(arm: ArmId, p: &[f64; 3]) -> bool {
        match arm {
            ArmId::Arm1 => p[1] >= -0.1,
            ArmId::Arm2 => p[1] <= 0.1,
        }
    }

    fn planner() -> AssignmentPlanner {
        AssignmentPlanner::new(PlannerConfig::default()).expect("default config")
    }

    #[test]
    fn ids_are_stable_across_sets_and_changes_are_counted() {
        let mut p = planner();
        let first = [[0.5, 0.3, 0.0], [0.6, -0.3, 0.0], [0.7, 0.2, 0.0]];
        let s = p.replan(&first, reach).expect("finite");
        assert_eq!((s.kept, s.dropped, s.added), (0, 0, 3));
        let id_of = |p: &AssignmentPlanner, y: f64| {
            ArmId::ALL
                .iter()
                .flat_map(|a| p.queue(*a).iter())
                .find(|a| (a.position_m[1] - y).abs() < 0.05)
                .map(|a| a.id)
        };
        let id_03 = id_of(&p, 0.3);
        // Second set: apple at y=0.3 moved 1 cm, apple at y=-0.3 gone, a new one at y=-0.2.
        let second = [[0.5, 0.31, 0.0], [0.7, 0.2, 0.0], [0.55, -0.2, 0.0]];
        let s = p.replan(&second, reach).expect("finite");
        assert_eq!((s.kept, s.dropped, s.added), (2, 1, 1));
        assert_eq!(id_of(&p, 0.31), id_03);
        let total: usize = ArmId::ALL.iter().map(|a| p.queue(*a).len()).sum();
        assert_eq!(total, 3);
    }

    #[test]
    fn in_progress_apple_survives_being_unseen_and_absorbs_its_detection() {
        let mut p = planner();
        p.replan(&[[0.5, 0.3, 0.0], [0.6, 0.25, 0.0]], reach)
            .expect("finite");
        let working = p.start_next(ArmId::Arm1).expect("arm 1 has apples");
        // Not seen: still in progress, not counted as dropped.
        let s = p.replan(&[[0.6, 0.25, 0.0]], reach).expect("finite");
        assert_eq!(p.in_progress(ArmId::Arm1), Some(working));
        assert_eq!((s.kept, s.dropped, s.added), (1, 0, 0));
        // Seen again: matched to the in-progress apple, not queued a second time.
        let s = p
            .replan(&[working.position_m, [0.6, 0.25, 0.0]], reach)
            .expect("finite");
        assert_eq!(s.added, 0);
        assert!(
            ArmId::ALL
                .iter()
                .all(|a| p.queue(*a).iter().all(|q| q.id != working.id))
        );
        // Busy arm cannot start another.
        assert_eq!(p.start_next(ArmId::Arm1), None);
    }

    #[test]
    fn failed_apple_is_retried_until_max_attempts_then_left() {
        let mut p = AssignmentPlanner::new(PlannerConfig {
            max_attempts: 2,
            ..PlannerConfig::default()
        })
        .expect("valid");
        let spot = [[0.5, 0.3, 0.0]];
        p.replan(&spot, reach).expect("finite");
        for attempt in 1..=2 {
            let a = p.start_next(ArmId::Arm1).expect("queued");
            assert_eq!(p.attempts(a.id), attempt);
            assert_eq!(p.finish(ArmId::Arm1, AttemptResult::Failed), Some(a));
            let s = p.replan(&spot, reach).expect("finite");
            assert_eq!(s.kept, 1);
            assert_eq!(s.exhausted, usize::from(attempt == 2));
        }
        assert!(p.queue(ArmId::Arm1).is_empty());
        assert_eq!(p.start_next(ArmId::Arm1), None);
    }

    #[test]
    fn a_free_arm_takes_the_busy_arm_queued_shared_apple_at_once() {
        let mut p = planner();
        // Two shared apples (reachable by both, |y| <= 0.1): arm 1 gets the one on its side.
        let set = [[0.5, 0.05, 0.0], [0.6, -0.05, 0.0]];
        p.replan(&set, reach).expect("finite");
        assert_eq!(
            (p.queue(ArmId::Arm1).len(), p.queue(ArmId::Arm2).len()),
            (1, 1)
        );
        // Both arms start; arm 2 is done first.
        let first = p.start_next(ArmId::Arm1).expect("queued");
        assert_eq!(first.position_m, set[0]);
        let second = p.start_next(ArmId::Arm2).expect("queued");
        p.finish(ArmId::Arm2, AttemptResult::Harvested);
        // Nothing to move while the free arm's own queue is not empty, or nothing waits.
        assert_eq!(p.rebalance_for(ArmId::Arm2, reach), Ok(false));
        // A third apple appears on arm 1's side; arm 1 is still busy: arm 2 takes it.
        p.replan(&[set[0], [0.55, 0.08, 0.0]], reach)
            .expect("finite");
        assert_eq!(p.queue(ArmId::Arm2).len(), 1);
        // Force the situation a re-plan without the rule would leave: arm 1 queued, arm 2 idle.
        let queued = p.plan.arm2.remove(0);
        p.plan.arm1.push(queued);
        assert_eq!(
            p.rebalance_for(ArmId::Arm1, reach),
            Ok(false),
            "arm 1 is busy"
        );
        assert_eq!(p.rebalance_for(ArmId::Arm2, reach), Ok(true));
        assert_eq!(p.queue(ArmId::Arm2), &[queued]);
        assert!(p.queue(ArmId::Arm1).is_empty());
        assert_ne!(second.id, queued.id);
    }

    #[test]
    fn an_apple_taken_back_is_not_an_attempt_and_waits_where_told() {
        let mut p = planner();
        // Arm 1 only: a and b; both arms: c.
        let set = [[0.5, 0.5, 0.0], [0.6, 0.4, 0.0], [0.7, 0.0, 0.0]];
        p.replan(&set, reach).expect("finite");
        let a = p.start_next(ArmId::Arm1).expect("queued");
        assert_eq!(p.attempts(a.id), 1);
        // Back to arm 1's own queue, behind its other apples.
        assert_eq!(p.take_back(ArmId::Arm1, ArmId::Arm1), Some(a));
        assert_eq!(p.attempts(a.id), 0);
        assert_eq!(p.queue(ArmId::Arm1).last(), Some(&a));
        assert_eq!(p.in_progress(ArmId::Arm1), None);
        assert_eq!(p.take_back(ArmId::Arm1, ArmId::Arm1), None, "idle");
        // To the head of the other arm's queue.
        let next = p.start_next(ArmId::Arm1).expect("queued");
        assert_ne!(next.id, a.id);
        assert_eq!(p.take_back(ArmId::Arm1, ArmId::Arm2), Some(next));
        assert_eq!(p.queue(ArmId::Arm2).first(), Some(&next));
        // Adopted by arm 1 after all: out of every queue, one attempt.
        assert_eq!(p.adopt(ArmId::Arm1, next.id), Some(next));
        assert!(p.queue(ArmId::Arm2).iter().all(|x| x.id != next.id));
        assert_eq!(p.attempts(next.id), 1);
        assert_eq!(p.in_progress(ArmId::Arm1), Some(next));
        assert_eq!(p.adopt(ArmId::Arm1, a.id), None, "busy");
    }

    #[test]
    fn harvested_apple_is_forgotten() {
        let mut p = planner();
        p.replan(&[[0.5, 0.3, 0.0]], reach).expect("finite");
        let a = p.start_next(ArmId::Arm1).expect("queued");
        p.finish(ArmId::Arm1, AttemptResult::Harvested);
        assert_eq!(p.attempts(a.id), 0);
        let s = p.replan(&[], reach).expect("finite");
        assert_eq!((s.kept, s.dropped, s.added), (0, 0, 0));
    }

    #[test]
    fn bad_input_and_config_are_refused_without_change() {
        let mut p = planner();
        p.replan(&[[0.5, 0.3, 0.0]], reach).expect("finite");
        assert!(p.replan(&[[f64::INFINITY, 0.0, 0.0]], reach).is_err());
        assert_eq!(p.queue(ArmId::Arm1).len(), 1);
        assert_eq!(
            AssignmentPlanner::new(PlannerConfig {
                match_radius_m: -1.0,
                ..PlannerConfig::default()
            })
            .err(),
            Some(PlannerConfigError::BadMatchRadius(-1.0))
        );
        let toml_text = "match_radius_m = 0.02\nmax_attempts = 2\n\
                         [frame]\nlateral_axis = \"Y\"\ndepth_axis = \"Z\"\narm1_side = \"Negative\"\n";
        let cfg: PlannerConfig = toml::from_str(toml_text).expect("valid");
        assert_eq!(cfg.frame, AssignmentFrame::PAPER_ALGORITHM_1);
        assert!(toml::from_str::<PlannerConfig>("match_radius = 0.02").is_err());
    }
}
