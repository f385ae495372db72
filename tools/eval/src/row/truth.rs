//! The ground truth of a row run (evaluation only): which apples the arms could reach at a stop,
//! with the chosen platform offsets and with the platform at its fixed position, and the
//! attribution of failed attempts to the categories of [dual-arm Table 3].
//!
//! Reach is the arm's own acceptance test ([`harvest_arm::node::pick_reachable`]: the picking
//! point has an inverse-kinematics solution within the joint limits and, with the other arm
//! present, keeps clear of it) applied to the true centres of the apples still on the tree.

use std::collections::BTreeMap;

use harvest_arm::node::{ArmNodeConfig, pick_reachable};
use harvest_sim::physics::ArmId;
use harvest_sim::{AppleState, World};
use serde::Serialize;

use crate::harvest::records::{AttemptRecord, FailureCause};

/// True apples on the tree in reach of one of `arms` (1: arm 1 alone, 2: both) when the robot
/// stands `shift_m` `[x, y, z]` further than now (robot frame).
pub fn reachable_apples(
    world: &World,
    arms: u8,
    shift_m: [f64; 3],
    config: &ArmNodeConfig,
) -> Vec<u32> {
    let enabled: &[ArmId] = if arms >= 2 {
        &ArmId::ALL
    } else {
        &ArmId::ALL[..1]
    };
    world
        .apples()
        .iter()
        .filter(|apple| apple.state == AppleState::OnTree)
        .filter(|apple| {
            let centre: [f64; 3] = std::array::from_fn(|i| apple.center_in_robot_m[i] - shift_m[i]);
            enabled
                .iter()
                .any(|&arm| pick_reachable(arm, centre, apple.radius_m, config))
        })
        .map(|apple| apple.id.0)
        .collect()
}

/// Table 3's categories ([dual-arm sec. 4.3]), plus what the paper does not list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Table3Cause {
    /// Perception: the target's apple is over-exposed.
    Exposure,
    /// Perception: the target's apple is heavily occluded.
    Occlusion,
    /// Perception: the target's apple is in a cluster.
    Cluster,
    /// Perception: a mislocalized target on an apple with none of the three flags.
    Localization,
    /// Perception: no apple within 15 cm of the target (a false detection).
    FalseDetection,
    /// Vacuum: a leaf prevented the seal.
    Sealing,
    /// Vacuum: the stem held; the apple slipped off.
    Detachment,
    /// Vacuum: a branch knocked the held apple off.
    Interference,
    /// Neither (low vacuum, release, approach timeout, valve, target not taken, ...).
    Other,
}

impl Table3Cause {
    /// All, in the table's order.
    pub const ALL: [Self; 9] = [
        Self::Exposure,
        Self::Occlusion,
        Self::Cluster,
        Self::Localization,
        Self::FalseDetection,
        Self::Sealing,
        Self::Detachment,
        Self::Interference,
        Self::Other,
    ];

    /// Column label.
    pub fn label(self) -> &'static str {
        match self {
            Self::Exposure => "Exposure",
            Self::Occlusion => "Occlusion",
            Self::Cluster => "Cluster",
            Self::Localization => "Localization",
            Self::FalseDetection => "False det.",
            Self::Sealing => "Sealing",
            Self::Detachment => "Detachment",
            Self::Interference => "Interference",
            Self::Other => "Other",
        }
    }

    /// The paper's count (Table 3), where it has the category.
    pub fn paper_count(self) -> Option<u32> {
        match self {
            Self::Exposure => Some(101),
            Self::Occlusion => Some(207),
            Self::Cluster => Some(159),
            Self::Sealing => Some(44),
            Self::Detachment => Some(22),
            Self::Interference => Some(14),
            _ => None,
        }
    }
}

/// The perception flags of a true apple as Table 3 causes (several may apply, as in the paper).
fn perception_flags(world: &World, apple: u32) -> Vec<Table3Cause> {
    let Some(apple) = world.apples().get(apple as usize) else {
        return vec![Table3Cause::Localization];
    };
    let mut causes = Vec::new();
    if apple.overexposed {
        causes.push(Table3Cause::Exposure);
    }
    if apple.heavily_occluded {
        causes.push(Table3Cause::Occlusion);
    }
    if apple.cluster.is_some() {
        causes.push(Table3Cause::Cluster);
    }
    if causes.is_empty() {
        causes.push(Table3Cause::Localization);
    }
    causes
}

/// The Table 3 causes of one failed attempt (empty for a harvested or unfinished one): a
/// target that matched no true apple within 5 cm, or that never came within the seal distance
/// of one ([`FailureCause::MissedApple`]), failed because of perception, attributed to the
/// flags of the nearest apple; the vacuum causes map one to one.
pub fn attempt_causes(world: &World, attempt: &AttemptRecord) -> Vec<Table3Cause> {
    if attempt.harvested || attempt.ended_s.is_none() {
        return Vec::new();
    }
    let perception = attempt.apple.is_none() || attempt.cause == Some(FailureCause::MissedApple);
    if perception {
        return match attempt.apple.or(attempt.near_apple) {
            Some(apple) => perception_flags(world, apple),
            None => vec![Table3Cause::FalseDetection],
        };
    }
    vec![match attempt.cause {
        Some(FailureCause::Sealing) => Table3Cause::Sealing,
        Some(FailureCause::Detachment) => Table3Cause::Detachment,
        Some(FailureCause::Interference) => Table3Cause::Interference,
        _ => Table3Cause::Other,
    }]
}

/// Apples in reach that no attempt aimed at and that are still on the tree: missed by
/// perception (or left by the assignment), by the flags of each apple.
pub fn missed_causes(world: &World, missed: &[u32]) -> BTreeMap<Table3Cause, u32> {
    let mut counts = BTreeMap::new();
    for &apple in missed {
        for cause in perception_flags(world, apple) {
            *counts.entry(cause).or_insert(0) += 1;
        }
    }
    counts
}
