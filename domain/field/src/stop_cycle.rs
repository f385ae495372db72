//! The stop-and-go cycle along a row ([dual-arm sec. 2.2 and 4.1]): the tractor halts at a
//! harvest location; with the arms parked the platform moves the robot so that the most
//! detected apples are in reach ([`crate::choose_offsets`]); after fresh detections the arms
//! harvest until nothing reachable is left; then the tractor advances to the next stop, by
//! itself (`auto_advance`) or on the operator's "next stop" ([`StopCycle::next_stop`], refused
//! while an arm holds an apple).
//!
//! [`StopCycle`] is transport-free: its owner (the executive, the one writer of the platform
//! and tractor commands) feeds it what the stack shows ([`FieldView`], attempts that ended) and
//! carries out the [`FieldAction`]s it returns.

use harvest_robot_model::params::ArmParams;

use crate::positioning::{StageTravel, choose_offsets, reachable_count};

/// How the row is worked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopCycleConfig {
    /// Stops along the row (the first is where the trailer stands at start).
    pub stops: u32,
    /// Distance between two stops, m.
    pub stop_spacing_m: f64,
    /// Advance by itself once a stop is harvested (else wait for the operator's "next stop").
    pub auto_advance: bool,
    /// The platform stages' travel.
    pub travel: StageTravel,
    /// A stop is harvested once the arms are parked and nothing happened (no assignment, no
    /// attempt) for this long after fresh detections, ns; or earlier, when the vacuum
    /// supervisor reports the harvest complete.
    pub quiet_ns: u64,
    /// A platform move or tractor advance not finished after this long is sent again (the
    /// device may have lost it, e.g. a restarted simulator), ns. Targets are absolute, so a
    /// repeat never moves further.
    pub resend_ns: u64,
}

/// What the stack shows at one tick.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldView {
    /// Trailer position along the row, m, and whether it moves (None: no feedback yet).
    pub tractor: Option<(f64, bool)>,
    /// Platform stage positions `[in_out, up_down]`, m, and whether they move.
    pub platform: Option<([f64; 2], bool)>,
    /// Both arms idle at home (no target, no motion).
    pub arms_parked: bool,
    /// Some arm holds an apple (attached, not yet dropped off).
    pub arms_holding: bool,
    /// The newest detection set: the camera frame's capture stamp and the apples' positions in
    /// the robot frame, m.
    pub detections: Option<(u64, Vec<[f64; 3]>)>,
}

/// What the owner must do.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldAction {
    /// Move the platform stages to `[in_out, up_down]`, m.
    MovePlatform { target_m: [f64; 2] },
    /// Drive the trailer `distance_m` further along the row.
    AdvanceTractor { distance_m: f64 },
    /// A stop was finished: its figures.
    StopFinished(StopReport),
    /// The last stop was finished: the row's figures.
    RowFinished(RowReport),
}

/// Where the cycle is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StopPhase {
    /// The trailer drives to the stop (since `since_ns`).
    Arriving { since_ns: u64 },
    /// Waiting for the arms to park and a detection set taken at rest (since `since_ns`).
    Parking { since_ns: u64 },
    /// The platform moves to the chosen offsets (sent at `sent_ns`).
    Positioning { target_m: [f64; 2], sent_ns: u64 },
    /// Waiting for a detection set captured after the platform came to rest (at `since_ns`).
    Settling { since_ns: u64 },
    /// The arms harvest; `last_activity_ns` is the newest assignment or attempt end.
    Harvesting { last_activity_ns: u64 },
    /// Harvested; waiting for the operator's "next stop".
    WaitingForOperator,
    /// The row is done.
    RowDone,
}

/// One stop's figures.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct StopReport {
    /// 1-based.
    pub stop: u32,
    /// Trailer position, m.
    pub trailer_m: f64,
    /// Platform offsets chosen `[in_out, up_down]`, m.
    pub offset_m: [f64; 2],
    /// Apples detected at the stop (before positioning).
    pub detected: usize,
    /// Detected apples in reach before positioning.
    pub reachable_before: usize,
    /// Predicted in reach at the chosen offsets.
    pub reachable_predicted: usize,
    /// Detected apples in reach after positioning (fresh detections).
    pub reachable_after: usize,
    /// Detected after positioning but out of reach of both arms: counted, not dropped.
    pub out_of_reach: usize,
    pub attempted: u32,
    pub harvested: u32,
    /// Apples perception published at a laser-refined position during the stop (distinct
    /// perception track ids).
    pub laser_refined: usize,
    /// Failed attempts by cause label.
    pub failures: Vec<(String, u32)>,
    /// Time at the stop from arrival to done, ns.
    pub duration_ns: u64,
}

/// The row's figures.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RowReport {
    pub stops: Vec<StopReport>,
    /// From the first arrival to the last stop done (travel and positioning included), ns.
    pub duration_ns: u64,
}

impl RowReport {
    pub fn detected(&self) -> usize {
        self.stops.iter().map(|s| s.detected).sum()
    }
    pub fn reachable(&self) -> usize {
        self.stops.iter().map(|s| s.reachable_after).sum()
    }
    pub fn out_of_reach(&self) -> usize {
        self.stops.iter().map(|s| s.out_of_reach).sum()
    }
    pub fn attempted(&self) -> u32 {
        self.stops.iter().map(|s| s.attempted).sum()
    }
    pub fn harvested(&self) -> u32 {
        self.stops.iter().map(|s| s.harvested).sum()
    }
    pub fn laser_refined(&self) -> usize {
        self.stops.iter().map(|s| s.laser_refined).sum()
    }
    /// Failures by cause over the row.
    pub fn failures(&self) -> Vec<(String, u32)> {
        let mut all: Vec<(String, u32)> = Vec::new();
        for (cause, count) in self.stops.iter().flat_map(|s| &s.failures) {
            match all.iter_mut().find(|(c, _)| c == cause) {
                Some(entry) => entry.1 += count,
                None => all.push((cause.clone(), *count)),
            }
        }
        all
    }
}

/// Why "next stop" was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NextStopRefusal {
    #[error("an arm holds an apple: drop it off first")]
    ArmsHoldApples,
    #[error("an arm is not parked: the trailer moves only with both arms parked")]
    ArmsNotParked,
    #[error("the trailer or the platform is moving")]
    InMotion,
    #[error("the row is done")]
    RowDone,
}

/// Why the cycle could not be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StopCycleError {
    #[error("stops {stops} must be at least 1")]
    NoStops { stops: u32 },
    #[error("stop spacing {spacing_m} m must be finite and positive")]
    Spacing { spacing_m: f64 },
}

/// The stop-and-go sequencer.
#[derive(Debug, Clone)]
pub struct StopCycle {
    config: StopCycleConfig,
    arms: [ArmParams; 2],
    phase: StopPhase,
    stop: StopReport,
    stop_started_ns: u64,
    row_started_ns: Option<u64>,
    /// Trailer position the current stop is at (None until known).
    stop_position_m: Option<f64>,
    done: Vec<StopReport>,
    /// An attempt ended or a target was assigned since the last tick.
    activity_ns: Option<u64>,
    /// The vacuum supervisor reported the harvest complete at this stamp.
    complete_ns: Option<u64>,
    /// Perception track ids seen laser-refined during the current stop.
    laser_refined_ids: Vec<u32>,
}

impl StopCycle {
    pub fn new(config: StopCycleConfig, arms: [ArmParams; 2]) -> Result<Self, StopCycleError> {
        if config.stops == 0 {
            return Err(StopCycleError::NoStops {
                stops: config.stops,
            });
        }
        if !(config.stop_spacing_m.is_finite() && config.stop_spacing_m > 0.0) {
            return Err(StopCycleError::Spacing {
                spacing_m: config.stop_spacing_m,
            });
        }
        Ok(Self {
            config,
            arms,
            phase: StopPhase::Arriving { since_ns: 0 },
            stop: StopReport {
                stop: 1,
                ..StopReport::default()
            },
            stop_started_ns: 0,
            row_started_ns: None,
            stop_position_m: None,
            done: Vec::new(),
            activity_ns: None,
            complete_ns: None,
            laser_refined_ids: Vec::new(),
        })
    }

    pub fn phase(&self) -> StopPhase {
        self.phase
    }

    /// True while new approaches must wait: the trailer drives, the arms park, the platform
    /// moves, or fresh detections are awaited (the owner tells the vacuum supervisor).
    pub fn holds_approaches(&self) -> bool {
        matches!(
            self.phase,
            StopPhase::Arriving { .. }
                | StopPhase::Parking { .. }
                | StopPhase::Positioning { .. }
                | StopPhase::Settling { .. }
        )
    }

    /// The stop being worked (1-based).
    pub fn stop_number(&self) -> u32 {
        self.stop.stop
    }

    /// The stops finished so far.
    pub fn finished_stops(&self) -> &[StopReport] {
        &self.done
    }

    /// A target was assigned to an arm (the stop is not done yet).
    pub fn on_assigned(&mut self, now_ns: u64) {
        self.activity_ns = Some(now_ns);
        self.complete_ns = None;
    }

    /// An attempt ended (`cause` labels a failure).
    pub fn on_attempt_ended(&mut self, now_ns: u64, harvested: bool, cause: &str) {
        self.activity_ns = Some(now_ns);
        if !matches!(self.phase, StopPhase::Harvesting { .. }) {
            // An attempt of an earlier phase (a restarted executive): still this stop's.
            tracing::debug!(?self.phase, "attempt ended outside the harvesting phase");
        }
        self.stop.attempted += 1;
        if harvested {
            self.stop.harvested += 1;
        } else {
            match self.stop.failures.iter_mut().find(|(c, _)| c == cause) {
                Some(entry) => entry.1 += 1,
                None => self.stop.failures.push((cause.to_owned(), 1)),
            }
        }
    }

    /// Perception published apple `apple_id` (its track id) at a laser-refined position:
    /// counted once for the current stop.
    pub fn on_laser_refined(&mut self, apple_id: u32) {
        if self.phase != StopPhase::RowDone && !self.laser_refined_ids.contains(&apple_id) {
            self.laser_refined_ids.push(apple_id);
            self.stop.laser_refined = self.laser_refined_ids.len();
        }
    }

    /// The vacuum supervisor reported that nothing is left to pick.
    pub fn on_harvest_complete(&mut self, now_ns: u64) {
        self.complete_ns = Some(now_ns);
    }

    /// The operator's "next stop": ends the stop's harvest and advances.
    pub fn next_stop(
        &mut self,
        now_ns: u64,
        view: &FieldView,
    ) -> Result<Vec<FieldAction>, NextStopRefusal> {
        if self.phase == StopPhase::RowDone {
            return Err(NextStopRefusal::RowDone);
        }
        if view.arms_holding {
            return Err(NextStopRefusal::ArmsHoldApples);
        }
        if !view.arms_parked {
            return Err(NextStopRefusal::ArmsNotParked);
        }
        let trailer_moving = view.tractor.is_some_and(|(_, moving)| moving);
        let platform_moving = view.platform.is_some_and(|(_, moving)| moving);
        if trailer_moving
            || platform_moving
            || matches!(
                self.phase,
                StopPhase::Arriving { .. } | StopPhase::Positioning { .. }
            )
        {
            return Err(NextStopRefusal::InMotion);
        }
        Ok(self.finish_stop(now_ns, view))
    }

    /// One tick: advances the phase from what the stack shows.
    pub fn tick(&mut self, now_ns: u64, view: &FieldView) -> Vec<FieldAction> {
        let row_started = *self.row_started_ns.get_or_insert(now_ns);
        let _ = row_started;
        match self.phase {
            StopPhase::Arriving { since_ns } => {
                if let (Some((position_m, _)), Some(target_m)) =
                    (view.tractor, self.stop_position_m)
                    && (position_m - target_m).abs() >= 0.01
                    && now_ns.saturating_sub(since_ns) >= self.config.resend_ns
                {
                    tracing::warn!(
                        position_m,
                        target_m,
                        "tractor not there yet: advance sent again"
                    );
                    self.phase = StopPhase::Arriving { since_ns: now_ns };
                    return vec![FieldAction::AdvanceTractor {
                        distance_m: target_m - position_m,
                    }];
                }
                if let Some((position_m, false)) = view.tractor {
                    let arrived = self
                        .stop_position_m
                        .is_none_or(|target| (position_m - target).abs() < 0.01);
                    if arrived {
                        self.stop_position_m = Some(position_m);
                        self.stop.trailer_m = position_m;
                        self.stop_started_ns = now_ns;
                        self.phase = StopPhase::Parking { since_ns: now_ns };
                        tracing::info!(stop = self.stop.stop, position_m, "at the stop");
                    }
                }
                Vec::new()
            }
            StopPhase::Parking { since_ns } => {
                let Some((current_m, false)) = view.platform else {
                    // A platform "moving" this long has lost its command (a restarted device
                    // never acts on it): hold the stages where they are.
                    if let Some((current_m, true)) = view.platform
                        && now_ns.saturating_sub(since_ns) >= self.config.resend_ns
                    {
                        tracing::warn!(?current_m, "platform still moving: held where it is");
                        self.phase = StopPhase::Parking { since_ns: now_ns };
                        return vec![FieldAction::MovePlatform {
                            target_m: current_m,
                        }];
                    }
                    return Vec::new();
                };
                let Some((capture_ns, apples)) = &view.detections else {
                    return Vec::new();
                };
                if !view.arms_parked || view.arms_holding || *capture_ns < self.stop_started_ns {
                    return Vec::new();
                }
                self.stop.detected = apples.len();
                let arms = [&self.arms[0], &self.arms[1]];
                match choose_offsets(arms, apples, self.config.travel, current_m) {
                    Ok(chosen) => {
                        self.stop.offset_m = chosen.offset_m;
                        self.stop.reachable_before = chosen.reachable_here;
                        self.stop.reachable_predicted = chosen.reachable;
                        tracing::info!(stop = self.stop.stop, ?chosen, "platform offsets chosen");
                        self.phase = StopPhase::Positioning {
                            target_m: chosen.offset_m,
                            sent_ns: now_ns,
                        };
                        vec![FieldAction::MovePlatform {
                            target_m: chosen.offset_m,
                        }]
                    }
                    Err(error) => {
                        tracing::warn!(%error, "no positioning: harvesting where the robot stands");
                        self.stop.offset_m = current_m;
                        self.stop.reachable_before = reachable_count(arms, apples, [0.0; 2]);
                        self.stop.reachable_predicted = self.stop.reachable_before;
                        self.phase = StopPhase::Settling { since_ns: now_ns };
                        Vec::new()
                    }
                }
            }
            StopPhase::Positioning { target_m, sent_ns } => {
                if let Some((at_m, false)) = view.platform
                    && (at_m[0] - target_m[0]).abs() < 1e-3
                    && (at_m[1] - target_m[1]).abs() < 1e-3
                {
                    self.phase = StopPhase::Settling { since_ns: now_ns };
                } else if now_ns.saturating_sub(sent_ns) >= self.config.resend_ns {
                    tracing::warn!(?target_m, "platform not there yet: move sent again");
                    self.phase = StopPhase::Positioning {
                        target_m,
                        sent_ns: now_ns,
                    };
                    return vec![FieldAction::MovePlatform { target_m }];
                }
                Vec::new()
            }
            StopPhase::Settling { since_ns } => {
                if let Some((capture_ns, apples)) = &view.detections
                    && *capture_ns > since_ns
                {
                    let arms = [&self.arms[0], &self.arms[1]];
                    let reachable = reachable_count(arms, apples, [0.0; 2]);
                    self.stop.reachable_after = reachable;
                    self.stop.out_of_reach = apples.len().saturating_sub(reachable);
                    self.complete_ns = None;
                    self.phase = StopPhase::Harvesting {
                        last_activity_ns: now_ns,
                    };
                }
                Vec::new()
            }
            StopPhase::Harvesting { last_activity_ns } => {
                let last = self
                    .activity_ns
                    .map_or(last_activity_ns, |a| a.max(last_activity_ns));
                self.phase = StopPhase::Harvesting {
                    last_activity_ns: last,
                };
                if !view.arms_parked || view.arms_holding {
                    return Vec::new();
                }
                let complete = self.complete_ns.is_some_and(|c| c >= last);
                let quiet = now_ns.saturating_sub(last) >= self.config.quiet_ns;
                if !(complete || quiet) {
                    return Vec::new();
                }
                if self.config.auto_advance {
                    self.finish_stop(now_ns, view)
                } else {
                    self.phase = StopPhase::WaitingForOperator;
                    tracing::info!(
                        stop = self.stop.stop,
                        "stop harvested: waiting for next stop"
                    );
                    Vec::new()
                }
            }
            StopPhase::WaitingForOperator | StopPhase::RowDone => Vec::new(),
        }
    }

    /// The tractor cannot drive to the next stop: the row ends before it (a row resumed part
    /// way has fewer stops left than `StopCycleConfig::stops`). Ends the row with the stops
    /// done; nothing if it is already done.
    pub fn row_ends_here(&mut self, now_ns: u64) -> Vec<FieldAction> {
        if self.phase == StopPhase::RowDone {
            return Vec::new();
        }
        tracing::info!(
            stops = self.done.len(),
            "the row ends before the next stop: row done"
        );
        vec![self.finish_row(now_ns)]
    }

    fn finish_row(&mut self, now_ns: u64) -> FieldAction {
        self.phase = StopPhase::RowDone;
        FieldAction::RowFinished(RowReport {
            stops: self.done.clone(),
            duration_ns: now_ns.saturating_sub(self.row_started_ns.unwrap_or(now_ns)),
        })
    }

    fn finish_stop(&mut self, now_ns: u64, view: &FieldView) -> Vec<FieldAction> {
        let _ = view;
        self.stop.duration_ns = now_ns.saturating_sub(self.stop_started_ns);
        let report = std::mem::take(&mut self.stop);
        let number = report.stop;
        self.done.push(report.clone());
        let mut actions = vec![FieldAction::StopFinished(report)];
        self.activity_ns = None;
        self.complete_ns = None;
        self.laser_refined_ids.clear();
        if number >= self.config.stops {
            actions.push(self.finish_row(now_ns));
            return actions;
        }
        self.stop = StopReport {
            stop: number + 1,
            ..StopReport::default()
        };
        self.stop_position_m = self
            .stop_position_m
            .map(|at| at + self.config.stop_spacing_m);
        self.phase = StopPhase::Arriving { since_ns: now_ns };
        actions.push(FieldAction::AdvanceTractor {
            distance_m: self.config.stop_spacing_m,
        });
        actions
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(auto_advance: bool) -> StopCycleConfig {
        StopCycleConfig {
            stops: 2,
            stop_spacing_m: 2.0,
            auto_advance,
            travel: StageTravel {
                in_out_max_m: 0.5,
                up_down_max_m: 0.8,
            },
            quiet_ns: 1_000,
            resend_ns: 1_000_000,
        }
    }

    fn cycle(auto_advance: bool) -> StopCycle {
        StopCycle::new(config(auto_advance), [ArmParams::arm1(), ArmParams::arm2()]).unwrap()
    }

    /// An apple in reach of arm 1 at the home position, one far out of reach.
    fn apples() -> Vec<[f64; 3]> {
        let arm = ArmParams::arm1();
        let (lo, hi) = (
            arm.position_limits.min.to_array(),
            arm.position_limits.max.to_array(),
        );
        let middle =
            harvest_robot_model::joint::JointPosition::from_array(std::array::from_fn(|i| {
                0.5 * (lo[i] + hi[i])
            }));
        let reach = harvest_robot_model::kinematics::forward(&arm.links, &middle);
        let apples = vec![reach, [5.0, 0.0, 0.0]];
        let arms = [ArmParams::arm1(), ArmParams::arm2()];
        assert_eq!(reachable_count([&arms[0], &arms[1]], &apples, [0.0; 2]), 1);
        apples
    }

    fn view(tractor_m: f64, platform_m: [f64; 2], capture_ns: u64) -> FieldView {
        FieldView {
            tractor: Some((tractor_m, false)),
            platform: Some((platform_m, false)),
            arms_parked: true,
            arms_holding: false,
            detections: Some((capture_ns, apples())),
        }
    }

    /// Drives one stop to its end; returns the actions of the last tick.
    fn harvest_stop(cycle: &mut StopCycle, t: &mut u64, trailer_m: f64) -> Vec<FieldAction> {
        *t += 10;
        assert!(cycle.tick(*t, &view(trailer_m, [0.0; 2], 0)).is_empty());
        assert!(matches!(cycle.phase(), StopPhase::Parking { .. }));
        *t += 10;
        let actions = cycle.tick(*t, &view(trailer_m, [0.0; 2], *t));
        let [FieldAction::MovePlatform { target_m }] = actions[..] else {
            panic!("{actions:?}")
        };
        *t += 10;
        cycle.tick(*t, &view(trailer_m, target_m, 0));
        assert!(matches!(cycle.phase(), StopPhase::Settling { .. }));
        // Detections older than the platform's rest do not count.
        *t += 10;
        cycle.tick(*t, &view(trailer_m, target_m, *t - 20));
        assert!(matches!(cycle.phase(), StopPhase::Settling { .. }));
        *t += 10;
        cycle.tick(*t, &view(trailer_m, target_m, *t));
        assert!(matches!(cycle.phase(), StopPhase::Harvesting { .. }));
        cycle.on_assigned(*t);
        cycle.on_attempt_ended(*t + 5, true, "");
        *t += 10;
        let busy = FieldView {
            arms_parked: false,
            ..view(trailer_m, target_m, *t)
        };
        assert!(cycle.tick(*t, &busy).is_empty());
        cycle.on_harvest_complete(*t + 1);
        *t += 10;
        cycle.tick(*t, &view(trailer_m, target_m, *t))
    }

    #[test]
    fn auto_advance_works_the_row_stop_by_stop() {
        let mut cycle = cycle(true);
        let mut t = 0;
        let actions = harvest_stop(&mut cycle, &mut t, 0.0);
        assert!(matches!(actions[0], FieldAction::StopFinished(ref r)
            if r.stop == 1 && r.harvested == 1 && r.attempted == 1 && r.detected == 2));
        assert_eq!(actions[1], FieldAction::AdvanceTractor { distance_m: 2.0 });
        // Still at the old place: not arrived.
        t += 10;
        cycle.tick(t, &view(0.0, [0.0; 2], t));
        assert!(matches!(cycle.phase(), StopPhase::Arriving { .. }));
        // A lost advance (the trailer never moved) is sent again, for the remaining distance.
        t += 1_000_000;
        assert_eq!(
            cycle.tick(t, &view(0.0, [0.0; 2], t)),
            vec![FieldAction::AdvanceTractor { distance_m: 2.0 }]
        );
        let actions = harvest_stop(&mut cycle, &mut t, 2.0);
        let Some(FieldAction::RowFinished(row)) = actions.last() else {
            panic!("{actions:?}")
        };
        assert_eq!(row.stops.len(), 2);
        assert_eq!(row.harvested(), 2);
        assert_eq!(
            row.out_of_reach(),
            2,
            "the far apple is counted at each stop"
        );
        assert_eq!(cycle.phase(), StopPhase::RowDone);
    }

    #[test]
    fn a_row_that_ends_before_the_next_stop_is_done_with_the_stops_worked() {
        // A row resumed at its last section: the cycle counts two stops from here, the tractor
        // refuses the advance past the row's end.
        let mut cycle = cycle(true);
        let mut t = 0;
        let actions = harvest_stop(&mut cycle, &mut t, 2.0);
        assert_eq!(
            actions.last(),
            Some(&FieldAction::AdvanceTractor { distance_m: 2.0 })
        );
        let actions = cycle.row_ends_here(t);
        let [FieldAction::RowFinished(row)] = actions.as_slice() else {
            panic!("{actions:?}")
        };
        assert_eq!(row.stops.len(), 1);
        assert_eq!(row.stops[0].trailer_m, 2.0);
        assert_eq!(row.harvested(), 1);
        assert_eq!(cycle.phase(), StopPhase::RowDone);
        // Nothing more: not a second row report, no advance sent again.
        assert!(cycle.row_ends_here(t).is_empty());
        t += 10_000_000_000;
        assert!(cycle.tick(t, &view(2.0, [0.0; 2], t)).is_empty());
        assert_eq!(
            cycle.next_stop(t, &view(2.0, [0.0; 2], t)),
            Err(NextStopRefusal::RowDone)
        );
    }

    #[test]
    fn without_auto_advance_the_operator_ends_the_stop_and_holding_arms_refuse() {
        let mut cycle = cycle(false);
        let mut t = 0;
        assert!(harvest_stop(&mut cycle, &mut t, 0.0).is_empty());
        assert_eq!(cycle.phase(), StopPhase::WaitingForOperator);
        let holding = FieldView {
            arms_holding: true,
            ..view(0.0, [0.0; 2], t)
        };
        assert_eq!(
            cycle.next_stop(t, &holding),
            Err(NextStopRefusal::ArmsHoldApples)
        );
        let actions = cycle.next_stop(t, &view(0.0, [0.0; 2], t)).unwrap();
        assert_eq!(
            actions.last(),
            Some(&FieldAction::AdvanceTractor { distance_m: 2.0 })
        );
        assert_eq!(
            cycle.next_stop(t, &view(0.0, [0.0; 2], t)),
            Err(NextStopRefusal::InMotion)
        );
    }

    #[test]
    fn next_stop_is_refused_while_the_platform_or_the_trailer_moves_and_after_the_row() {
        let mut cycle = cycle(false);
        let mut t = 0;
        assert!(harvest_stop(&mut cycle, &mut t, 0.0).is_empty());
        assert_eq!(cycle.phase(), StopPhase::WaitingForOperator);
        let platform_moving = FieldView {
            platform: Some(([0.1, 0.1], true)),
            ..view(0.0, [0.0; 2], t)
        };
        assert_eq!(
            cycle.next_stop(t, &platform_moving),
            Err(NextStopRefusal::InMotion)
        );
        let trailer_moving = FieldView {
            tractor: Some((0.3, true)),
            ..view(0.0, [0.0; 2], t)
        };
        assert_eq!(
            cycle.next_stop(t, &trailer_moving),
            Err(NextStopRefusal::InMotion)
        );
        let arm_out = FieldView {
            arms_parked: false,
            ..view(0.0, [0.0; 2], t)
        };
        assert_eq!(
            cycle.next_stop(t, &arm_out),
            Err(NextStopRefusal::ArmsNotParked)
        );
        assert_eq!(
            cycle.phase(),
            StopPhase::WaitingForOperator,
            "a refusal changes nothing"
        );
        // Stop 1 ends on the operator's word, stop 2 too: then the row is done.
        let actions = cycle.next_stop(t, &view(0.0, [0.0; 2], t)).unwrap();
        assert!(matches!(
            actions.first(),
            Some(FieldAction::StopFinished(_))
        ));
        let actions = harvest_stop(&mut cycle, &mut t, 2.0);
        assert!(actions.is_empty(), "{actions:?}");
        let actions = cycle.next_stop(t, &view(2.0, [0.0; 2], t)).unwrap();
        assert!(matches!(actions.last(), Some(FieldAction::RowFinished(_))));
        assert_eq!(
            cycle.next_stop(t, &view(2.0, [0.0; 2], t)),
            Err(NextStopRefusal::RowDone)
        );
    }

    #[test]
    fn a_stop_with_nothing_happening_ends_after_the_quiet_time() {
        let mut cycle = cycle(true);
        let mut t = 0;
        cycle.tick(t, &view(0.0, [0.0; 2], 0));
        t += 10;
        let actions = cycle.tick(t, &view(0.0, [0.0; 2], t));
        let [FieldAction::MovePlatform { target_m }] = actions[..] else {
            panic!("{actions:?}")
        };
        cycle.tick(t + 1, &view(0.0, target_m, 0));
        cycle.tick(t + 2, &view(0.0, target_m, t + 2));
        assert!(
            cycle
                .tick(t + 500, &view(0.0, target_m, t + 500))
                .is_empty()
        );
        let actions = cycle.tick(t + 2_000, &view(0.0, target_m, t + 2_000));
        assert!(matches!(actions[0], FieldAction::StopFinished(ref r) if r.attempted == 0));
    }

    #[test]
    fn bad_configuration_is_refused() {
        let arms = [ArmParams::arm1(), ArmParams::arm2()];
        let mut bad = config(true);
        bad.stops = 0;
        assert!(matches!(
            StopCycle::new(bad, arms),
            Err(StopCycleError::NoStops { .. })
        ));
        let mut bad = config(true);
        bad.stop_spacing_m = f64::NAN;
        assert!(matches!(
            StopCycle::new(bad, arms),
            Err(StopCycleError::Spacing { .. })
        ));
    }
}
