//! Contact physics of vacuum harvesting: seal, attach, detach, hold, drop and release, driven by
//! the end-effector positions the caller feeds in and by the vacuum model of [`vacuum`].
//!
//! Per arm and step ([dual-arm sec. 2.2-2.3 and 4.3]):
//! - seal: the cup is within `seal_distance_m` (1.5 cm) of an apple's surface, the arm's inlet
//!   valve is commanded open and no leaf is in between. Whether a leaf blocks is drawn once per
//!   attempt (apple and valve opening) with probability `failures.seal_failure`;
//! - attach: once sealed and the holding force `F = F_max P_arm / P_max` reaches
//!   `attach_min_force_n`; the fruit then moves rigidly with the cup;
//! - detach: the stem pulls back with `k_stem * max(0, stretch - slack)`; it lets go when that
//!   tension reaches the stem strength, lowered by twisting the cup
//!   (`strength * (1 - relief * min(1, |twist| / twist_full))`), provided the cup holds that much;
//!   otherwise the cup slips off (insufficient detachment force);
//! - hold: a detached fruit falls when the holding force drops below `hold_min_force_n`, or when
//!   the injected holding interference (drawn at detachment with `failures.holding_interference`)
//!   knocks it off after a random retract travel;
//! - release: closing the inlet vents the line; the fruit falls when the force is gone. Over the
//!   dropping module it is harvested, elsewhere dropped.

pub mod servo;
pub mod vacuum;

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::orchard::{AppleId, AppleState, World};
use crate::scenario::{VacuumConfig, norm, sub};
use vacuum::{VacuumPlantState, inlet_valve};

/// Arm 1 is served by valves 1-2, arm 2 by valves 3-4 (paper numbering).
pub use harvest_ipc::ArmId;

/// What the caller feeds in every step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInputs {
    /// Tip of each arm's end-effector (cup), robot frame, metres; `[arm 1, arm 2]`.
    pub end_effector_in_robot_m: [[f64; 3]; 2],
    /// Rotation of each cup about its axis, radians (twisting helps detach).
    pub end_effector_twist_rad: [f64; 2],
    /// Commanded state of butterfly valves 1-4 (true = open).
    pub valve_open: [bool; 4],
}

impl StepInputs {
    /// Valve commands for the coordination logic's `Open_Valve_i`: arm `i` open = inlet open and
    /// vent shut; closed = inlet shut and vent open to the atmosphere.
    pub fn valves_for_arms(open: [bool; 2]) -> [bool; 4] {
        [open[0], !open[0], open[1], !open[1]]
    }
}

/// Why a detached apple fell before release.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DropCause {
    /// A branch knocked it off during the retract (Table 3, "Interference").
    HoldingInterference,
    /// The vacuum dropped below what holds it while the inlet was still open.
    LowVacuum,
}

/// Where a released apple ended up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReleaseOutcome {
    /// On the dropping module.
    Harvested,
    /// On the ground.
    Dropped,
    /// It was never detached, so it stays on the tree.
    BackOnTree,
}

/// Something that happened to an apple during a step (ground truth; the robot only sees the
/// pressures).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WorldEvent {
    /// A leaf between cup and fruit prevented the seal for this attempt (Table 3, "Sealing").
    SealBlocked { arm: ArmId, apple: AppleId },
    /// The cup sealed on the fruit and holds it.
    Attached { arm: ArmId, apple: AppleId },
    /// The stem let go; the fruit is off the tree, on the cup.
    Detached { arm: ArmId, apple: AppleId },
    /// The stem held harder than the cup: the fruit slipped off the cup and stays on the tree
    /// (Table 3, "Detachment").
    Slipped {
        arm: ArmId,
        apple: AppleId,
        tension_n: f64,
        holding_force_n: f64,
    },
    /// A detached fruit fell off the cup before release.
    Dropped {
        arm: ArmId,
        apple: AppleId,
        cause: DropCause,
    },
    /// The inlet closed and the fruit left the cup.
    Released {
        arm: ArmId,
        apple: AppleId,
        outcome: ReleaseOutcome,
    },
}

/// Why a step was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The step length is not a positive finite number of seconds.
    #[error("world step dt_s = {dt_s} must be > 0 and finite")]
    InvalidTimeStep { dt_s: f64 },
    /// An end-effector position or twist is NaN or infinite.
    #[error("arm {arm:?}: end-effector input {value:?} is not finite")]
    NonFiniteInput { arm: ArmId, value: [f64; 4] },
}

/// One harvest attempt: the arm's inlet is open near this apple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Attempt {
    /// Index of the apple in [`World::apples`].
    pub(crate) apple: usize,
    pub(crate) seal_blocked: bool,
    /// The cup already slipped off this apple; no new seal until the valve closes.
    pub(crate) exhausted: bool,
}

/// A fruit on the cup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Held {
    /// Index of the apple in [`World::apples`].
    pub(crate) apple: usize,
    /// Apple centre minus cup position at the moment of sealing, robot frame.
    pub(crate) offset_m: [f64; 3],
    pub(crate) twist_at_seal_rad: f64,
    /// Where the cup was when the stem let go.
    pub(crate) detach_point_m: Option<[f64; 3]>,
    /// Retract travel after which an injected interference knocks the fruit off.
    pub(crate) interference_travel_m: Option<f64>,
}

/// What one arm's cup is doing: the attempt under way and the fruit it holds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct ArmContact {
    pub(crate) attempt: Option<Attempt>,
    pub(crate) held: Option<Held>,
}

/// Mutable physics state inside [`World`].
#[derive(Debug, Clone)]
pub(crate) struct PhysicsState {
    pub(crate) vacuum: VacuumPlantState,
    pub(crate) arms: [ArmContact; 2],
    rng: SmallRng,
    time_s: f64,
}

/// Decorrelates the physics random stream from the generation stream of the same seed.
const PHYSICS_STREAM: u64 = 0x9e37_79b9_7f4a_7c15;

impl PhysicsState {
    pub(crate) fn new(config: &VacuumConfig, seed: u64) -> Self {
        Self {
            vacuum: VacuumPlantState::at_rest(config),
            arms: [ArmContact::default(); 2],
            rng: SmallRng::seed_from_u64(seed ^ PHYSICS_STREAM),
            time_s: 0.0,
        }
    }
}

impl World {
    /// Pressures and valve positions (what the three pressure sensors would read).
    pub fn vacuum(&self) -> VacuumPlantState {
        self.physics.vacuum
    }

    /// Simulated time since generation, seconds.
    pub fn time_s(&self) -> f64 {
        self.physics.time_s
    }

    /// The apple arm `arm` holds, if any.
    pub fn held_apple(&self, arm: ArmId) -> Option<AppleId> {
        self.physics.arms[arm.index()]
            .held
            .map(|held| self.apples[held.apple].id)
    }

    /// Advances the world by `dt_s` (valves, pressures, contacts) and reports what happened.
    pub fn step(&mut self, dt_s: f64, inputs: &StepInputs) -> Result<Vec<WorldEvent>, StepError> {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return Err(StepError::InvalidTimeStep { dt_s });
        }
        for arm in ArmId::ALL {
            let [x, y, z] = inputs.end_effector_in_robot_m[arm.index()];
            let twist = inputs.end_effector_twist_rad[arm.index()];
            if ![x, y, z, twist].iter().all(|v| v.is_finite()) {
                return Err(StepError::NonFiniteInput {
                    arm,
                    value: [x, y, z, twist],
                });
            }
        }
        let config = self.scenario.vacuum.clone();
        let cups = ArmId::ALL.map(|arm| self.cup_conductance(&config, arm, inputs));
        self.physics
            .vacuum
            .step(&config, dt_s, inputs.valve_open, cups);
        let mut events = Vec::new();
        for arm in ArmId::ALL {
            self.step_arm(&config, arm, inputs, &mut events);
        }
        self.physics.time_s += dt_s;
        for event in &events {
            tracing::trace!(?event, time_s = self.physics.time_s, "world event");
        }
        Ok(events)
    }

    /// Conductance of the arm's cup: sealed by a held fruit, partly blocked by a leaf over the
    /// attempted fruit, or open to the air.
    fn cup_conductance(&self, config: &VacuumConfig, arm: ArmId, inputs: &StepInputs) -> f64 {
        let contact = &self.physics.arms[arm.index()];
        if contact.held.is_some() {
            return config.sealed_cup_conductance;
        }
        if let Some(attempt) = contact.attempt
            && attempt.seal_blocked
            && self.surface_gap_m(attempt.apple, inputs.end_effector_in_robot_m[arm.index()])
                <= config.seal_distance_m
        {
            return config.leaf_blocked_cup_conductance;
        }
        config.open_cup_conductance
    }

    fn surface_gap_m(&self, apple: usize, cup_m: [f64; 3]) -> f64 {
        let apple = &self.apples[apple];
        norm(sub(cup_m, apple.center_in_robot_m)) - apple.radius_m
    }

    /// The closest apple on the tree whose surface is within the seal distance of the cup.
    fn sealable_apple(&self, config: &VacuumConfig, cup_m: [f64; 3]) -> Option<usize> {
        self.apples
            .iter()
            .enumerate()
            .filter(|(_, apple)| apple.state == AppleState::OnTree)
            .map(|(index, _)| (index, self.surface_gap_m(index, cup_m)))
            .filter(|(_, gap)| *gap <= config.seal_distance_m)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(index, _)| index)
    }

    fn step_arm(
        &mut self,
        config: &VacuumConfig,
        arm: ArmId,
        inputs: &StepInputs,
        events: &mut Vec<WorldEvent>,
    ) {
        let a = arm.index();
        let cup = inputs.end_effector_in_robot_m[a];
        let twist = inputs.end_effector_twist_rad[a];
        let inlet_commanded_open = inputs.valve_open[inlet_valve(a)];
        let force = self.physics.vacuum.holding_force_n(config, a);
        if !inlet_commanded_open {
            self.physics.arms[a].attempt = None;
        }
        if let Some(held) = self.physics.arms[a].held {
            self.step_held(
                config,
                arm,
                held,
                cup,
                twist,
                inlet_commanded_open,
                force,
                events,
            );
            return;
        }
        if !inlet_commanded_open {
            return;
        }
        let Some(apple) = self.sealable_apple(config, cup) else {
            return;
        };
        let attempt = match self.physics.arms[a].attempt {
            Some(attempt) if attempt.apple == apple => attempt,
            _ => {
                let seal_blocked = self
                    .physics
                    .rng
                    .random_bool(self.scenario.failures.seal_failure);
                if seal_blocked {
                    events.push(WorldEvent::SealBlocked {
                        arm,
                        apple: self.apples[apple].id,
                    });
                }
                let attempt = Attempt {
                    apple,
                    seal_blocked,
                    exhausted: false,
                };
                self.physics.arms[a].attempt = Some(attempt);
                attempt
            }
        };
        if attempt.seal_blocked || attempt.exhausted || force < config.attach_min_force_n {
            return;
        }
        let center = self.apples[apple].center_in_robot_m;
        self.physics.arms[a].held = Some(Held {
            apple,
            offset_m: sub(center, cup),
            twist_at_seal_rad: twist,
            detach_point_m: None,
            interference_travel_m: None,
        });
        self.apples[apple].state = AppleState::Attached {
            arm,
            detached: false,
        };
        events.push(WorldEvent::Attached {
            arm,
            apple: self.apples[apple].id,
        });
    }

    #[allow(clippy::too_many_arguments)]
    fn step_held(
        &mut self,
        config: &VacuumConfig,
        arm: ArmId,
        mut held: Held,
        cup: [f64; 3],
        twist: f64,
        inlet_commanded_open: bool,
        force: f64,
        events: &mut Vec<WorldEvent>,
    ) {
        let a = arm.index();
        let index = held.apple;
        let id = self.apples[index].id;
        let center: [f64; 3] = std::array::from_fn(|k| cup[k] + held.offset_m[k]);
        self.apples[index].center_in_robot_m = center;
        match held.detach_point_m {
            None => {
                let stems = &self.scenario.stems;
                let apple = &self.apples[index];
                let stretch = norm(sub(center, apple.rest_center_in_robot_m)) - stems.slack_m;
                let tension = stems.stiffness_n_per_m * stretch.max(0.0);
                let relief = stems.twist_relief
                    * ((twist - held.twist_at_seal_rad).abs() / stems.twist_full_rad).min(1.0);
                let strength = apple.stem_strength_n * (1.0 - relief);
                let holding = force >= config.hold_min_force_n;
                if holding && tension >= strength && strength <= force {
                    held.detach_point_m = Some(cup);
                    if self
                        .physics
                        .rng
                        .random_bool(self.scenario.failures.holding_interference)
                    {
                        let [low, high] = config.interference_travel_m;
                        held.interference_travel_m = Some(if high > low {
                            self.physics.rng.random_range(low..high)
                        } else {
                            low
                        });
                    }
                    self.physics.arms[a].held = Some(held);
                    self.apples[index].state = AppleState::Attached {
                        arm,
                        detached: true,
                    };
                    events.push(WorldEvent::Detached { arm, apple: id });
                } else if !holding || tension > force {
                    self.let_go_on_tree(a);
                    events.push(if inlet_commanded_open {
                        WorldEvent::Slipped {
                            arm,
                            apple: id,
                            tension_n: tension,
                            holding_force_n: force,
                        }
                    } else {
                        WorldEvent::Released {
                            arm,
                            apple: id,
                            outcome: ReleaseOutcome::BackOnTree,
                        }
                    });
                }
            }
            Some(detach_point) => {
                let knocked_off = held
                    .interference_travel_m
                    .is_some_and(|travel| norm(sub(cup, detach_point)) >= travel);
                if knocked_off {
                    self.fall(a, false);
                    events.push(WorldEvent::Dropped {
                        arm,
                        apple: id,
                        cause: DropCause::HoldingInterference,
                    });
                } else if force < config.hold_min_force_n {
                    if inlet_commanded_open {
                        self.fall(a, false);
                        events.push(WorldEvent::Dropped {
                            arm,
                            apple: id,
                            cause: DropCause::LowVacuum,
                        });
                    } else {
                        let harvested = center[0] <= config.dropping_module_max_x_m;
                        self.fall(a, harvested);
                        events.push(WorldEvent::Released {
                            arm,
                            apple: id,
                            outcome: if harvested {
                                ReleaseOutcome::Harvested
                            } else {
                                ReleaseOutcome::Dropped
                            },
                        });
                    }
                }
            }
        }
    }

    /// The cup lets go of a fruit still on its stem: it springs back to its rest position.
    fn let_go_on_tree(&mut self, arm: usize) {
        let Some(held) = self.physics.arms[arm].held.take() else {
            return;
        };
        let apple = &mut self.apples[held.apple];
        apple.center_in_robot_m = apple.rest_center_in_robot_m;
        apple.state = AppleState::OnTree;
        if let Some(attempt) = self.physics.arms[arm].attempt.as_mut() {
            attempt.exhausted = true;
        }
    }

    /// A detached fruit leaves the cup: onto the dropping module or the ground.
    fn fall(&mut self, arm: usize, harvested: bool) {
        let Some(held) = self.physics.arms[arm].held.take() else {
            return;
        };
        let ground_z = self.scenario.background.ground_z_m;
        let apple = &mut self.apples[held.apple];
        if harvested {
            apple.state = AppleState::Harvested;
        } else {
            apple.state = AppleState::Dropped;
            apple.center_in_robot_m[2] = ground_z + apple.radius_m;
        }
        self.physics.arms[arm].attempt = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    /// A cup far from any apple (near the arm's home position).
    const HOME: [f64; 3] = [0.95, 0.0, 0.2];
    const DT: f64 = 0.01;

    fn ideal_world() -> World {
        World::generate(&Scenario::preset("ideal").expect("ideal"), 1).expect("world")
    }

    /// Point `gap_m` in front of apple 0's surface, on the side facing the robot.
    fn in_front_of(world: &World, apple: usize, gap_m: f64) -> [f64; 3] {
        let a = &world.apples()[apple];
        let c = a.center_in_robot_m;
        [c[0] - a.radius_m - gap_m, c[1], c[2]]
    }

    fn inputs(arm1_cup: [f64; 3], arm1_open: bool) -> StepInputs {
        StepInputs {
            end_effector_in_robot_m: [arm1_cup, HOME],
            end_effector_twist_rad: [0.0; 2],
            valve_open: StepInputs::valves_for_arms([arm1_open, false]),
        }
    }

    fn run(world: &mut World, seconds: f64, inputs: &StepInputs) -> Vec<WorldEvent> {
        let mut all = Vec::new();
        for _ in 0..(seconds / DT).round() as usize {
            all.extend(world.step(DT, inputs).expect("step"));
        }
        all
    }

    #[test]
    fn no_attach_with_the_valve_closed() {
        let mut world = ideal_world();
        let cup = in_front_of(&world, 0, 0.005);
        let events = run(&mut world, 2.0, &inputs(cup, false));
        assert!(events.is_empty(), "{events:?}");
        assert_eq!(world.apples()[0].state, AppleState::OnTree);
    }

    #[test]
    fn no_attach_beyond_the_seal_distance() {
        let mut world = ideal_world();
        let cup = in_front_of(&world, 0, 0.02);
        let events = run(&mut world, 2.0, &inputs(cup, true));
        assert!(events.is_empty(), "{events:?}");
        assert!(world.vacuum().arm_mmh2o[0] > 100.0, "the line does pump");
    }

    #[test]
    fn attaches_within_the_seal_distance_with_the_valve_open_and_releases_on_close() {
        let mut world = ideal_world();
        let cup = in_front_of(&world, 0, 0.012);
        let events = run(&mut world, 1.5, &inputs(cup, true));
        let id = world.apples()[0].id;
        assert_eq!(
            events,
            vec![WorldEvent::Attached {
                arm: ArmId::Arm1,
                apple: id
            }]
        );
        assert_eq!(world.held_apple(ArmId::Arm1), Some(id));
        // Sealed: the arm line climbs close to the source.
        let vacuum = world.vacuum();
        assert!(vacuum.arm_mmh2o[0] > 0.9 * vacuum.source_mmh2o);
        // Close the valve without pulling: the fruit returns to its stem.
        let events = run(&mut world, 1.5, &inputs(cup, false));
        assert_eq!(
            events,
            vec![WorldEvent::Released {
                arm: ArmId::Arm1,
                apple: id,
                outcome: ReleaseOutcome::BackOnTree
            }]
        );
        assert_eq!(world.apples()[0].state, AppleState::OnTree);
    }

    #[test]
    fn pull_detaches_and_closing_over_the_dropping_module_harvests() {
        let mut world = ideal_world();
        let id = world.apples()[0].id;
        let cup = in_front_of(&world, 0, 0.005);
        run(&mut world, 1.0, &inputs(cup, true));
        assert_eq!(world.held_apple(ArmId::Arm1), Some(id));
        // Retract in 1 cm steps to the home position with the valve open.
        let mut events = Vec::new();
        let mut position = cup;
        while position[0] > HOME[0] {
            position[0] -= 0.01;
            events.extend(world.step(DT, &inputs(position, true)).expect("step"));
        }
        assert_eq!(
            events,
            vec![WorldEvent::Detached {
                arm: ArmId::Arm1,
                apple: id
            }]
        );
        let events = run(&mut world, 1.5, &inputs(position, false));
        assert_eq!(
            events,
            vec![WorldEvent::Released {
                arm: ArmId::Arm1,
                apple: id,
                outcome: ReleaseOutcome::Harvested
            }]
        );
        assert_eq!(world.apples()[0].state, AppleState::Harvested);
    }

    #[test]
    fn a_leaf_blocks_the_seal_when_injected() {
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.failures.seal_failure = 1.0;
        let mut world = World::generate(&scenario, 1).expect("world");
        let cup = in_front_of(&world, 0, 0.005);
        let events = run(&mut world, 2.0, &inputs(cup, true));
        assert_eq!(
            events,
            vec![WorldEvent::SealBlocked {
                arm: ArmId::Arm1,
                apple: world.apples()[0].id
            }]
        );
        assert_eq!(world.apples()[0].state, AppleState::OnTree);
    }

    #[test]
    fn a_stem_stronger_than_the_cup_makes_it_slip() {
        let mut world = ideal_world();
        world.apples[0].stem_strength_n = 80.0;
        let id = world.apples()[0].id;
        let cup = in_front_of(&world, 0, 0.005);
        run(&mut world, 1.0, &inputs(cup, true));
        let mut events = Vec::new();
        let mut position = cup;
        for _ in 0..20 {
            position[0] -= 0.01;
            events.extend(world.step(DT, &inputs(position, true)).expect("step"));
        }
        assert!(
            matches!(events.as_slice(), [WorldEvent::Slipped { apple, tension_n, holding_force_n, .. }]
                if *apple == id && tension_n > holding_force_n),
            "{events:?}"
        );
        assert_eq!(world.apples()[0].state, AppleState::OnTree);
        assert_eq!(
            world.apples()[0].center_in_robot_m,
            world.apples()[0].rest_center_in_robot_m
        );
    }

    #[test]
    fn twisting_lowers_the_pull_needed() {
        let pull_needed = |twist: f64| {
            let mut world = ideal_world();
            world.apples[0].stem_strength_n = 30.0;
            let cup = in_front_of(&world, 0, 0.005);
            run(&mut world, 1.0, &inputs(cup, true));
            let mut position = cup;
            for step in 1..100 {
                position[0] -= 0.001;
                let mut input = inputs(position, true);
                input.end_effector_twist_rad[0] = twist;
                let events = world.step(DT, &input).expect("step");
                if events
                    .iter()
                    .any(|e| matches!(e, WorldEvent::Detached { .. }))
                {
                    return step;
                }
            }
            usize::MAX
        };
        assert!(pull_needed(1.57) < pull_needed(0.0));
    }

    #[test]
    fn injected_interference_drops_the_fruit_during_the_retract() {
        let mut scenario = Scenario::preset("ideal").expect("ideal");
        scenario.failures.holding_interference = 1.0;
        let mut world = World::generate(&scenario, 1).expect("world");
        let cup = in_front_of(&world, 0, 0.005);
        run(&mut world, 1.0, &inputs(cup, true));
        let mut events = Vec::new();
        let mut position = cup;
        for _ in 0..60 {
            position[0] -= 0.01;
            events.extend(world.step(DT, &inputs(position, true)).expect("step"));
        }
        assert!(
            matches!(
                events.as_slice(),
                [
                    WorldEvent::Detached { .. },
                    WorldEvent::Dropped {
                        cause: DropCause::HoldingInterference,
                        ..
                    }
                ]
            ),
            "{events:?}"
        );
        assert_eq!(world.apples()[0].state, AppleState::Dropped);
    }

    #[test]
    fn same_seed_same_event_sequence() {
        let trace = |seed: u64| {
            let mut scenario = Scenario::preset("ideal").expect("ideal");
            scenario.failures.seal_failure = 0.5;
            let mut world = World::generate(&scenario, seed).expect("world");
            let mut events = Vec::new();
            for apple in 0..world.apples().len() {
                let cup = in_front_of(&world, apple, 0.005);
                events.extend(run(&mut world, 1.0, &inputs(cup, true)));
                events.extend(run(&mut world, 1.0, &inputs(HOME, false)));
            }
            events
        };
        assert_eq!(trace(3), trace(3));
        assert!(!trace(3).is_empty());
    }

    #[test]
    fn bad_inputs_are_refused() {
        let mut world = ideal_world();
        assert!(world.step(0.0, &inputs(HOME, false)).is_err());
        assert!(
            world
                .step(DT, &inputs([f64::NAN, 0.0, 0.0], false))
                .is_err()
        );
    }
}
