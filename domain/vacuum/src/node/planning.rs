//! Step 2 and the give-up list: a detection set re-plans the assignment (leaving out apples
//! held in a cup and spots given up), dispatched targets still seen are refreshed, and a free
//! arm gets its share of the other arm's queue.

use tracing::{debug, trace, warn};

use super::{Reachability, VacuumNode, VacuumNodeConfig, VacuumNodeEvent};
use harvest_ipc::payloads::{AppleDetections, ArmPhase as PhaseCode, ArmState};
use harvest_robot_model::ArmId;

/// Radius used when a detection carries none, m.
const FALLBACK_RADIUS_M: f64 = 0.04;
/// Cup positions recorded this long before a set's capture still count as "at capture" (the
/// arm state seen by the node is up to a control period old), ns.
const CAPTURE_SLACK_NS: u64 = 20_000_000;

impl VacuumNode {
    /// Records where each carrying arm's cup is now (its [`super::cup_trail::CupTrail`]).
    pub(super) fn record_cups(&mut self, arm_states: &[Option<&ArmState>; 2], now_ns: u64) {
        for (trail, state) in self.cup_trails.iter_mut().zip(arm_states) {
            if let Some(cup) = state.and_then(holding_cup_m) {
                trail.push(now_ns, cup);
            }
        }
    }

    /// Step 2: a new detection set. Detections of an apple held in a cup (see
    /// [`VacuumNodeConfig::held_margin_m`]), now or where the cup was since the set's capture
    /// (perception's latency), are left out before planning.
    pub(super) fn replan(
        &mut self,
        set: &AppleDetections,
        arm_states: &[Option<&ArmState>; 2],
        now_ns: u64,
    ) {
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
                let captured_from_ns = set.source_capture_ns.saturating_sub(CAPTURE_SLACK_NS);
                if cups
                    .iter()
                    .flatten()
                    .chain(
                        self.cup_trails
                            .iter()
                            .flat_map(|t| t.since(captured_from_ns)),
                    )
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
    pub(super) fn radius_of(&self, position_m: &[f64; 3]) -> f64 {
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
    /// `max_attempts`. Returns the spot that counted it.
    pub(super) fn remember(&mut self, position_m: &[f64; 3]) -> &mut ([f64; 3], u32) {
        let r2 = self.config.give_up_radius_m.powi(2);
        let nearest = self
            .attempt_spots
            .iter()
            .enumerate()
            .map(|(index, spot)| (squared_distance(&spot.0, position_m), index))
            .filter(|(d2, _)| *d2 <= r2)
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, index)| index);
        let index = match nearest {
            Some(index) => {
                let (p, attempts) = &mut self.attempt_spots[index];
                let n = f64::from(*attempts);
                for (c, new) in p.iter_mut().zip(position_m) {
                    *c = (*c * n + new) / (n + 1.0);
                }
                *attempts += 1;
                index
            }
            None => {
                self.attempt_spots.push((*position_m, 1));
                self.attempt_spots.len() - 1
            }
        };
        &mut self.attempt_spots[index]
    }

    /// Puts `position_m` on the give-up list at once (its spot counts `planner.max_attempts`
    /// attempts): an apple no further attempt can harvest.
    pub(super) fn give_up(&mut self, position_m: &[f64; 3]) {
        let limit = self.config.planner.max_attempts;
        let spot = self.remember(position_m);
        spot.1 = spot.1.max(limit);
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

    /// Gives the free `arm` its share of the apples queued for the other arm at once (see
    /// [`AssignmentPlanner::rebalance_for`](crate::replan::AssignmentPlanner::rebalance_for)) instead of at the next detection set.
    pub(super) fn rebalance_for(&mut self, arm: ArmId, now_ns: u64) {
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
}

/// The cup of an arm whose end-effector carries (or may carry) an apple away from the tree:
/// it holds one (`ArmState::holding`), or it retracts or releases. `None` otherwise, or when
/// the end-effector position is not finite.
fn holding_cup_m(state: &ArmState) -> Option<[f64; 3]> {
    let carrying = state.holding != 0
        || matches!(
            state.phase.get(),
            Ok(PhaseCode::Retract | PhaseCode::Release)
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
