//! Choosing the platform's in-out and up-down offsets at a stop.
//!
//! Moving the stages by `d = [d_in_out, d_up_down]` from where they stand moves the robot by
//! `d` toward the canopy and up, so an apple seen at `p` (robot frame) is then at
//! `p - [d_in_out, 0, d_up_down]`. An apple counts as in reach at an offset when one of the
//! two arms has an inverse-kinematics solution within its joint limits (eq. 1, Table 1;
//! [`harvest_robot_model::kinematics::inverse`]) whose tube body keeps
//! [`harvest_robot_model::clearance::DEFAULT_CLEARANCE_M`] from the other arm parked at home
//! (the other arm is parked while its partner reaches, or works elsewhere: the conservative
//! case). The offsets are searched on a grid over the whole travel (step
//! [`GRID_STEP_M`], both ends included); among the offsets with the most apples in reach the
//! one nearest the current position wins (less travel, less time).

use harvest_robot_model::clearance::{DEFAULT_CLEARANCE_M, TubeSegment, segment_distance_m};
use harvest_robot_model::kinematics::inverse;
use harvest_robot_model::params::ArmParams;

/// Grid step of the offset search, m.
pub const GRID_STEP_M: f64 = 0.02;

/// The stages' travel: each spans `[0, max]` from its stop, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageTravel {
    pub in_out_max_m: f64,
    pub up_down_max_m: f64,
}

/// What was chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Positioning {
    /// Stage positions to move to `[in_out, up_down]`, m from their stops (inside the travel).
    pub offset_m: [f64; 2],
    /// Apples in reach of either arm there.
    pub reachable: usize,
    /// Apples in reach at the current position.
    pub reachable_here: usize,
}

/// Why no positioning could be chosen.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PositioningError {
    #[error("stage travel {travel:?} must be finite and positive on both stages")]
    InvalidTravel { travel: StageTravel },
    #[error(
        "current stage position {current_m:?} m is outside the travel {travel:?} or not finite"
    )]
    CurrentOutsideTravel {
        current_m: [f64; 2],
        travel: StageTravel,
    },
}

/// True when `apple_m` (robot frame) is in reach of `arm` with `other` parked at home.
fn in_reach(arm: &ArmParams, other: &ArmParams, apple_m: [f64; 3]) -> bool {
    let Ok(q) = inverse(arm, apple_m) else {
        return false;
    };
    let reaching = TubeSegment::at(&arm.links, &q);
    let parked = TubeSegment::at(&other.links, &other.home);
    segment_distance_m(&reaching, &parked) >= DEFAULT_CLEARANCE_M
}

/// Apples of `apples_m` (robot frame at the current position) in reach of either arm after
/// the stages move by `delta_m` `[in_out, up_down]`.
pub fn reachable_count(arms: [&ArmParams; 2], apples_m: &[[f64; 3]], delta_m: [f64; 2]) -> usize {
    apples_m
        .iter()
        .filter(|apple| {
            let moved = [apple[0] - delta_m[0], apple[1], apple[2] - delta_m[1]];
            in_reach(arms[0], arms[1], moved) || in_reach(arms[1], arms[0], moved)
        })
        .count()
}

/// Grid values over `[0, max]`, both ends included.
fn grid(max_m: f64) -> impl Iterator<Item = f64> {
    let steps = (max_m / GRID_STEP_M).ceil().max(1.0) as usize;
    (0..=steps).map(move |k| (k as f64 * GRID_STEP_M).min(max_m))
}

/// The stage positions (inside `travel`) that put the most of `apples_m` in reach; the
/// apples are in the robot frame with the stages at `current_m`.
pub fn choose_offsets(
    arms: [&ArmParams; 2],
    apples_m: &[[f64; 3]],
    travel: StageTravel,
    current_m: [f64; 2],
) -> Result<Positioning, PositioningError> {
    let maxima = [travel.in_out_max_m, travel.up_down_max_m];
    if !maxima.iter().all(|m| m.is_finite() && *m > 0.0) {
        return Err(PositioningError::InvalidTravel { travel });
    }
    let inside = current_m
        .iter()
        .zip(maxima)
        .all(|(value, max)| value.is_finite() && (0.0..=max).contains(value));
    if !inside {
        return Err(PositioningError::CurrentOutsideTravel { current_m, travel });
    }
    let reachable_here = reachable_count(arms, apples_m, [0.0; 2]);
    let mut best = Positioning {
        offset_m: current_m,
        reachable: reachable_here,
        reachable_here,
    };
    let mut best_travel_m = 0.0;
    for in_out in grid(maxima[0]) {
        for up_down in grid(maxima[1]) {
            let delta = [in_out - current_m[0], up_down - current_m[1]];
            let count = reachable_count(arms, apples_m, delta);
            let travel_m = delta[0].abs().max(delta[1].abs());
            if count > best.reachable || (count == best.reachable && travel_m < best_travel_m) {
                best.offset_m = [in_out, up_down];
                best.reachable = count;
                best_travel_m = travel_m;
            }
        }
    }
    tracing::debug!(?best, apples = apples_m.len(), "platform offsets chosen");
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::orchard::{AppleState, World};
    use harvest_sim::row::RowScenario;

    fn arms() -> [ArmParams; 2] {
        [ArmParams::arm1(), ArmParams::arm2()]
    }

    const TRAVEL: StageTravel = StageTravel {
        in_out_max_m: 0.5,
        up_down_max_m: 0.8,
    };

    /// A row of `sections` sections of `preset`, each 2 m apart, placed as the preset rows
    /// place theirs (`sim/rows/three_sections.toml`'s `[placement]`: canopy set back and
    /// fruiting zone lifted per section); the stops are at the sections' centres (the robot's
    /// y = 0 on the section's middle).
    fn stops(preset: &str, seed: u64, sections: usize) -> Vec<Vec<[f64; 3]>> {
        let preset_row = RowScenario::from_toml_str(
            "three_sections.toml",
            include_str!("../../../sim/rows/three_sections.toml"),
        )
        .expect("preset row");
        let placement = preset_row.file.placement;
        let mut text = format!(
            "name = \"measure\"\n[placement]\ncanopy_setback_m = {:?}\nfruiting_zone_lift_m = {:?}\n",
            placement.canopy_setback_m, placement.fruiting_zone_lift_m
        );
        for index in 0..sections {
            text.push_str(&format!(
                "[[section]]\ncanopy = \"{preset}\"\ncenter_m = {}\n",
                2.0 * index as f64
            ));
        }
        let row = RowScenario::from_toml_str("measure.toml", &text).expect("row");
        let mut world = World::generate_row(&row, seed).expect("world");
        (0..sections)
            .map(|index| {
                world.set_robot_offset_m([0.0, 2.0 * index as f64, 0.0]);
                world
                    .apples()
                    .iter()
                    .filter(|apple| apple.state == AppleState::OnTree)
                    .map(|apple| apple.center_in_robot_m)
                    .collect()
            })
            .collect()
    }

    #[test]
    fn chosen_offsets_respect_the_travel_and_never_lose_apples() {
        let [a1, a2] = arms();
        for apples in stops("default", 1, 3) {
            for current in [[0.0, 0.0], [0.25, 0.4], [0.5, 0.8]] {
                let chosen = choose_offsets([&a1, &a2], &apples, TRAVEL, current).expect("chosen");
                assert!((0.0..=TRAVEL.in_out_max_m).contains(&chosen.offset_m[0]));
                assert!((0.0..=TRAVEL.up_down_max_m).contains(&chosen.offset_m[1]));
                assert!(chosen.reachable >= chosen.reachable_here);
                let delta = [
                    chosen.offset_m[0] - current[0],
                    chosen.offset_m[1] - current[1],
                ];
                assert_eq!(
                    reachable_count([&a1, &a2], &apples, delta),
                    chosen.reachable
                );
            }
        }
    }

    #[test]
    fn bad_travel_and_positions_are_refused() {
        let [a1, a2] = arms();
        let bad = StageTravel {
            in_out_max_m: f64::NAN,
            up_down_max_m: 0.8,
        };
        assert!(matches!(
            choose_offsets([&a1, &a2], &[], bad, [0.0; 2]),
            Err(PositioningError::InvalidTravel { .. })
        ));
        assert!(matches!(
            choose_offsets([&a1, &a2], &[], TRAVEL, [0.6, 0.0]),
            Err(PositioningError::CurrentOutsideTravel { .. })
        ));
    }

    /// What positioning buys: apples in reach per stop with the chosen offsets vs the
    /// fixed position (stages at their stops), on the same generated rows. Prints the figures
    /// (`cargo test -p harvest-field --release -- --nocapture positioning_beats`).
    #[test]
    fn positioning_beats_the_fixed_position_on_generated_rows() {
        let [a1, a2] = arms();
        let mut total = [0usize; 3]; // apples, fixed, chosen
        // Apples of the stop's own section (within 1 m along the row: half the spacing of the
        // stops) out of reach at the chosen offsets: all, and those an arm would reach if the
        // apple stood straight ahead of the robot (y = 0) at the same depth and height: beyond
        // the arms' sideways (yaw) reach, which no stage moves; only stops closer together
        // along the row can bring them in.
        let mut out_of_reach = [0usize; 2];
        for preset in ["default", "gala_vertical_wall", "fuji_ufo"] {
            let mut per_preset = [0usize; 3];
            for seed in 1..=3 {
                for apples in stops(preset, seed, 3) {
                    let chosen =
                        choose_offsets([&a1, &a2], &apples, TRAVEL, [0.0; 2]).expect("chosen");
                    per_preset[0] += apples.len();
                    per_preset[1] += chosen.reachable_here;
                    per_preset[2] += chosen.reachable;
                    let delta = chosen.offset_m;
                    for apple in &apples {
                        let moved = [apple[0] - delta[0], apple[1], apple[2] - delta[1]];
                        let reach = |p: [f64; 3]| in_reach(&a1, &a2, p) || in_reach(&a2, &a1, p);
                        if moved[1].abs() <= 1.0 && !reach(moved) {
                            out_of_reach[0] += 1;
                            out_of_reach[1] += usize::from(reach([moved[0], 0.0, moved[2]]));
                        }
                    }
                }
            }
            println!(
                "positioning {preset:>20}: {} stops, apples {} , reachable fixed {} , chosen {} , ratio {:.2}",
                9,
                per_preset[0],
                per_preset[1],
                per_preset[2],
                per_preset[2] as f64 / per_preset[1].max(1) as f64
            );
            for k in 0..3 {
                total[k] += per_preset[k];
            }
        }
        // The same rows with the up-down stops centred on the row frame's z = 0 (a stage
        // range of [-0.4, 0.4] m): the fixed position is the stage's middle (the robot at
        // z = 0, as at the default stops above); the chosen offsets may also go down.
        let mut centred = [0usize; 2];
        for preset in ["default", "gala_vertical_wall", "fuji_ufo"] {
            for seed in 1..=3 {
                for apples in stops(preset, seed, 3) {
                    let chosen =
                        choose_offsets([&a1, &a2], &apples, TRAVEL, [0.0, 0.4]).expect("chosen");
                    centred[0] += chosen.reachable_here;
                    centred[1] += chosen.reachable;
                }
            }
        }
        println!(
            "positioning centred up-down stops: reachable per stop fixed {:.1} , chosen {:.1} , ratio {:.2}",
            centred[0] as f64 / 27.0,
            centred[1] as f64 / 27.0,
            centred[1] as f64 / centred[0].max(1) as f64
        );
        println!(
            "positioning out of reach at the chosen offsets, within 1 m of the stop: {} apples, {} \
({:.0} %) only sideways (in reach at y = 0, same depth and height)",
            out_of_reach[0],
            out_of_reach[1],
            100.0 * out_of_reach[1] as f64 / out_of_reach[0].max(1) as f64
        );
        let ratio = total[2] as f64 / total[1].max(1) as f64;
        println!(
            "positioning all: apples {} , reachable per stop fixed {:.1} , chosen {:.1} , ratio {ratio:.2}",
            total[0],
            total[1] as f64 / 27.0,
            total[2] as f64 / 27.0
        );
        assert!(
            total[2] > total[1],
            "chosen {} vs fixed {}",
            total[2],
            total[1]
        );
    }
}
