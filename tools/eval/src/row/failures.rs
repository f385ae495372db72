//! What lies behind each failed attempt of a row run (evaluation only): the simulator's ground
//! truth (the leaf and branch draws, the apple's stem against the cup's force, which apple the
//! target was near and in what state) next to the stack's decision that led to it (the target
//! perception gave, how far from the true centre; the attempt's rank on its apple).
//!
//! Each failed attempt gets one [`FailureOrigin`]: whether the simulator's stochastic models
//! decided it whatever the stack does (a leaf over the fruit, a stem stronger than the cup at
//! full vacuum, a branch on the retract path) or a decision of the stack did (a target on an
//! apple already picked, on nothing, too far from the apple to seal, a pull with the vacuum
//! sagged).

use std::collections::BTreeMap;

use harvest_sim::World;
use serde::Serialize;

use super::truth::{Table3Cause, attempt_causes};
use crate::harvest::records::{
    AppleStateKind, AttemptRecord, FailureCause, NearestApple, SlipForces, TARGET_MATCH_M,
};

/// What decided a failed attempt.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FailureOrigin {
    /// Simulator: the per-attempt leaf draw blocked the seal (`failures.seal_failure`).
    LeafDraw,
    /// Simulator: the stem is stronger than the cup's force at full vacuum even with the
    /// largest twist relief (an unripe stem, `failures.insufficient_detachment_force`).
    StemBeyondCup,
    /// Stack: the stem was within the cup's full-vacuum force, but the fruit slipped with the
    /// holding force below it (vacuum sagged) or too little twist.
    StemWithinCup,
    /// Simulator: the per-detachment branch draw knocked the fruit off
    /// (`failures.holding_interference`).
    BranchDraw,
    /// Stack: the target was within 5 cm of an apple no longer on the tree (in a cup, on the
    /// module, on the ground): a detection of an apple already dealt with.
    StaleTarget,
    /// Stack (perception): no apple of any state within 5 cm of the target.
    NoAppleAtTarget,
    /// Stack (perception): the target was within 5 cm of an apple on the tree but the cup
    /// never came within the seal distance of it.
    MissedSeal,
    /// Anything else (low vacuum drop, timeout, target not taken, ...).
    Other,
}

impl FailureOrigin {
    /// All, in the table's order.
    pub const ALL: [Self; 8] = [
        Self::LeafDraw,
        Self::StemBeyondCup,
        Self::BranchDraw,
        Self::StemWithinCup,
        Self::StaleTarget,
        Self::NoAppleAtTarget,
        Self::MissedSeal,
        Self::Other,
    ];

    /// Column label.
    pub fn label(self) -> &'static str {
        match self {
            Self::LeafDraw => "leaf draw",
            Self::StemBeyondCup => "stem>cup",
            Self::BranchDraw => "branch draw",
            Self::StemWithinCup => "stem<=cup",
            Self::StaleTarget => "stale target",
            Self::NoAppleAtTarget => "no apple",
            Self::MissedSeal => "missed seal",
            Self::Other => "other",
        }
    }

    /// Decided by the simulator's stochastic models whatever the stack does (once attempted).
    pub fn simulator_decided(self) -> bool {
        matches!(
            self,
            Self::LeafDraw | Self::StemBeyondCup | Self::BranchDraw
        )
    }
}

/// One failed attempt and the ground truth behind it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailedAttempt {
    /// Arm number.
    pub arm: u8,
    /// Dispatch time, s since the run began.
    pub dispatched_s: f64,
    pub origin: FailureOrigin,
    /// The harvest evaluation's cause.
    pub cause: Option<FailureCause>,
    /// Table 3 categories.
    pub table3: Vec<Table3Cause>,
    /// The true apple aimed at (within 5 cm), its rank among the attempts on it (1 = first).
    pub apple: Option<u32>,
    pub attempt_on_apple: u32,
    /// Target to true centre, mm (perception's picking-point error at dispatch).
    pub target_error_mm: Option<f64>,
    /// The nearest true apple in any state.
    pub nearest: Option<NearestApple>,
    /// The aimed apple's stem strength, N, and the strength left at full twist relief.
    pub stem_strength_n: Option<f64>,
    pub stem_with_relief_n: Option<f64>,
    /// Forces when it slipped.
    pub slip: Option<SlipForces>,
}

/// The failed attempts of one run, in dispatch order.
pub fn failed_attempts(world: &World, attempts: &[AttemptRecord]) -> Vec<FailedAttempt> {
    let scenario = world.scenario();
    let full_force_n = scenario.vacuum.suction_force_at_max_vacuum_n;
    let relief = scenario.stems.twist_relief;
    let mut rank: BTreeMap<u32, u32> = BTreeMap::new();
    let mut out = Vec::new();
    for attempt in attempts {
        let attempt_on_apple = attempt.apple.map_or(1, |apple| {
            let n = rank.entry(apple).or_insert(0);
            *n += 1;
            *n
        });
        if attempt.harvested || attempt.ended_s.is_none() {
            continue;
        }
        let stem_strength_n = attempt
            .apple
            .and_then(|id| world.apples().get(id as usize))
            .map(|a| a.stem_strength_n);
        let stem_with_relief_n = stem_strength_n.map(|s| s * (1.0 - relief));
        let origin = match attempt.cause {
            Some(FailureCause::Sealing) => FailureOrigin::LeafDraw,
            Some(FailureCause::Interference) => FailureOrigin::BranchDraw,
            Some(FailureCause::Detachment) => {
                if stem_with_relief_n.is_some_and(|s| s > full_force_n) {
                    FailureOrigin::StemBeyondCup
                } else {
                    FailureOrigin::StemWithinCup
                }
            }
            _ if attempt.apple.is_none() => match &attempt.nearest_any {
                Some(n) if n.distance_m < TARGET_MATCH_M && n.state != AppleStateKind::OnTree => {
                    FailureOrigin::StaleTarget
                }
                _ => FailureOrigin::NoAppleAtTarget,
            },
            Some(FailureCause::MissedApple) => FailureOrigin::MissedSeal,
            _ => FailureOrigin::Other,
        };
        out.push(FailedAttempt {
            arm: attempt.arm,
            dispatched_s: attempt.dispatched_s,
            origin,
            cause: attempt.cause,
            table3: attempt_causes(world, attempt),
            apple: attempt.apple,
            attempt_on_apple,
            target_error_mm: attempt.target_error_m.map(|m| m * 1e3),
            nearest: attempt.nearest_any.clone(),
            stem_strength_n,
            stem_with_relief_n,
            slip: attempt.slip,
        });
    }
    out
}

/// Counts by origin.
pub fn origin_counts(failed: &[FailedAttempt]) -> BTreeMap<FailureOrigin, u32> {
    let mut counts = BTreeMap::new();
    for f in failed {
        *counts.entry(f.origin).or_insert(0) += 1;
    }
    counts
}

/// One line of the per-attempt table.
pub fn render_line(f: &FailedAttempt) -> String {
    let opt =
        |v: Option<f64>, unit: &str| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.1}{unit}"));
    let nearest = f.nearest.as_ref().map_or_else(
        || "-".to_owned(),
        |n| format!("{} {:?} @{:.0} mm", n.apple, n.state, n.distance_m * 1e3),
    );
    let slip = f.slip.map_or_else(
        || "-".to_owned(),
        |s| format!("{:.1}/{:.1} N", s.tension_n, s.holding_force_n),
    );
    format!(
        "arm {} t {:>6.1} s {:<12} {:<14} apple {:>4} #{} err {:>8} stem {:>7} (relief {:>7}) slip t/F {:>13} nearest {}",
        f.arm,
        f.dispatched_s,
        f.origin.label(),
        f.cause.map_or_else(|| "-".to_owned(), |c| format!("{c:?}")),
        f.apple.map_or_else(|| "-".to_owned(), |a| a.to_string()),
        f.attempt_on_apple,
        opt(f.target_error_mm, " mm"),
        opt(f.stem_strength_n, " N"),
        opt(f.stem_with_relief_n, " N"),
        slip,
        nearest
    )
}

/// Apples left on the tree after a slip: their last attempt failed with the fruit slipping off
/// the cup (the vacuum supervisor gives such an apple up at once when the cup held full
/// vacuum; counted here, never silently dropped).
pub fn left_after_slip(world: &World, attempts: &[AttemptRecord]) -> u32 {
    let mut last: BTreeMap<u32, &AttemptRecord> = BTreeMap::new();
    for attempt in attempts {
        if let Some(apple) = attempt.apple {
            last.insert(apple, attempt);
        }
    }
    last.iter()
        .filter(|(apple, attempt)| {
            attempt.cause == Some(FailureCause::Detachment)
                && world
                    .apples()
                    .get(**apple as usize)
                    .is_some_and(|a| a.state == harvest_sim::AppleState::OnTree)
        })
        .count() as u32
}
