//! The world's state on disk, so a restart of the sim process continues the same row exactly
//! where it stood: the same apples (the world is regenerated from its scenario and seed), the
//! same harvested and dropped apples, the trailer and the platform where they stood, and the
//! robot as it was: each arm's joints, the apple each cup held (sealed on its stem or
//! already detached, at the same place on the cup) and the attempt under way, the valves'
//! commands and openings, and the vacuum's pressures. A fruit on a cup at a `kill -9` therefore
//! stays on the cup and is counted once, when it is released over the dropping module.
//!
//! The file (TOML) is by default `<iceoryx2 root>/harvest-sim/<domain>.world.toml`
//! (`/tmp/iceoryx2/harvest-sim/` with the stack's iceoryx2 configuration, beside the domain's
//! `harvest up` lock; [`default_state_path`]). It is written to a temporary file in the same
//! folder, synced, then renamed over the old one: a reader (or a restart after `kill -9`) sees
//! either the old state or the new one, never a torn file. The physics thread writes it
//! ([`WorldStatePersister`]):
//! - at once ([`WorldStatePersister::store_now`]) after a physics step in which an apple
//!   changed hands (seal, detach, slip, drop, release) or the valves were commanded, before the
//!   readings of that step are published: what the stack has seen of the world is on disk;
//! - otherwise when it changed (the arms' joints, the pressures, the trailer and the platform
//!   move continuously), at most once per [`WorldStatePersister::min_interval`], and once more
//!   when the thread stops. A restart after `kill -9` puts these back as they were at most that
//!   interval before the kill; the arms' controllers see their joints there and go on from
//!   there.
//!
//! Not kept: the simulated clock and the random stream of the failure draws (seal blocked,
//! interference), which restart from the seed; a restart is a fresh draw, not a replay.
//!
//! At start the sim loads the file when present and it belongs to the same world (scenario or
//! row name, seed, apple count); a file of another world is reported and replaced. A file
//! without the robot's part (written before it existed) restores the apples and positions with
//! the arms at home, an apple a cup held then counting as dropped if its stem had let go.

use crate::orchard::{AppleId, AppleState, World};
use crate::physics::vacuum::VacuumPlantState;
use crate::physics::{ArmContact, Attempt, Held};
use crate::robot::{ARM_JOINTS, SimRobot, SimRobotError, VALVES};
use harvest_ipc::ArmId;
use harvest_ipc::Domain;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Folder of the state files under the iceoryx2 root.
const STATE_FOLDER: &str = "harvest-sim";

/// What an apple off the tree became.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OffTree {
    Harvested,
    Dropped,
}

/// One apple that is no longer on its tree.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OffTreeApple {
    pub apple_id: u32,
    pub state: OffTree,
    /// Where it lies (on the dropping module or the ground), robot frame, m.
    pub center_in_robot_m: [f64; 3],
}

/// The persisted state of one world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldState {
    /// Scenario or row name of the world.
    pub world: String,
    pub seed: u64,
    /// Apples in the generated world (a check that the file fits the world).
    pub apple_count: usize,
    /// Trailer position along the row, m.
    pub trailer_m: f64,
    /// Platform stage positions `[in_out, up_down]`, m from their stops.
    pub platform_m: [f64; 2],
    /// Apples harvested or dropped, by id.
    pub off_tree: Vec<OffTreeApple>,
    /// The robot's arms, cups, valves and vacuum (absent in files written without them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<RobotState>,
}

/// The robot's part of the world's state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotState {
    /// Commanded position of valves 1-4 (true = open).
    pub valves_open: [bool; VALVES],
    /// Opening of valves 1-4, 0 = shut, 1 = fully open.
    pub valve_opening: [f64; VALVES],
    /// Vacuum at the source, mmH2O below atmosphere.
    pub source_mmh2o: f64,
    /// Vacuum inside arm 1 and arm 2, mmH2O below atmosphere.
    pub arm_mmh2o: [f64; 2],
    /// Both arms.
    pub arms: Vec<ArmState>,
}

/// One arm: its joints and what its cup is doing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmState {
    pub arm: ArmId,
    /// Joint positions `[D m, theta rad, phi rad, twist rad]`.
    pub joint_position: [f64; ARM_JOINTS],
    /// Joint rates `[D m/s, theta rad/s, phi rad/s, twist rad/s]`.
    pub joint_velocity: [f64; ARM_JOINTS],
    /// The attempt under way (the inlet is open near this apple).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attempt: Option<AttemptState>,
    /// The apple on the cup.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held: Option<HeldApple>,
}

/// A harvest attempt under way.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AttemptState {
    pub apple_id: u32,
    /// A leaf blocks the seal for this attempt.
    pub seal_blocked: bool,
    /// The cup already slipped off this apple.
    pub exhausted: bool,
}

/// An apple on a cup.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldApple {
    pub apple_id: u32,
    /// Apple centre, robot frame, m.
    pub center_in_robot_m: [f64; 3],
    /// Apple centre minus cup position at the moment of sealing, robot frame, m.
    pub offset_m: [f64; 3],
    /// Cup twist when it sealed, rad.
    pub twist_at_seal_rad: f64,
    /// Where the cup was when the stem let go, robot frame, m (absent: still on its stem).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub detach_point_m: Option<[f64; 3]>,
    /// Retract travel after which an injected interference knocks it off, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interference_travel_m: Option<f64>,
}

/// Why the state file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum WorldStateError {
    #[error("world state file {path}: cannot {action}: {source}")]
    Io {
        path: PathBuf,
        action: &'static str,
        source: std::io::Error,
    },
    #[error("world state file {path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("world state: cannot encode: {0}")]
    Encode(String),
    #[error("world state file {path}: `{key}` = {value}: {problem}")]
    Invalid {
        path: PathBuf,
        key: String,
        value: String,
        problem: &'static str,
    },
    #[error("world state: restoring the robot: {0}")]
    Robot(#[from] SimRobotError),
}

/// `<iceoryx2 root>/harvest-sim/<domain>.world.toml`.
pub fn default_state_path(domain: &Domain) -> PathBuf {
    let root = domain.iceoryx2_config().global.root_path().to_string();
    Path::new(&root)
        .join(STATE_FOLDER)
        .join(format!("{}.world.toml", domain.name()))
}

impl WorldState {
    /// The state of `world` with the trailer at `trailer_m` and the stages at `platform_m`.
    pub fn of(world: &World, trailer_m: f64, platform_m: [f64; 2]) -> Self {
        let off_tree = world
            .apples()
            .iter()
            .filter_map(|apple| {
                let state = match apple.state {
                    AppleState::OnTree
                    | AppleState::Attached {
                        detached: false, ..
                    } => {
                        return None;
                    }
                    AppleState::Harvested => OffTree::Harvested,
                    AppleState::Dropped | AppleState::Attached { detached: true, .. } => {
                        OffTree::Dropped
                    }
                };
                Some(OffTreeApple {
                    apple_id: apple.id.0,
                    state,
                    center_in_robot_m: apple.center_in_robot_m,
                })
            })
            .collect();
        Self {
            world: world.scenario().name.clone(),
            seed: world.seed(),
            apple_count: world.apples().len(),
            trailer_m,
            platform_m,
            off_tree,
            robot: None,
        }
    }

    /// The state of `robot`'s world and of the robot itself (arms, cups, valves, vacuum), with
    /// the trailer at `trailer_m` and the stages at `platform_m`. Apples on a cup are recorded
    /// with their arm, not as off the tree.
    pub fn of_robot(robot: &SimRobot, trailer_m: f64, platform_m: [f64; 2]) -> Self {
        let world = robot.world();
        let mut state = Self::of(world, trailer_m, platform_m);
        state.off_tree.retain(|entry| {
            !matches!(
                world
                    .apples
                    .get(entry.apple_id as usize)
                    .map(|apple| apple.state),
                Some(AppleState::Attached { .. })
            )
        });
        let vacuum = world.vacuum();
        let apple_id = |index: usize| world.apples[index].id.0;
        let arms = ArmId::ALL
            .into_iter()
            .map(|arm| {
                let contact = world.physics.arms[arm.index()];
                let (joint_position, joint_velocity) = robot.encoders(arm);
                ArmState {
                    arm,
                    joint_position,
                    joint_velocity,
                    attempt: contact.attempt.map(|attempt| AttemptState {
                        apple_id: apple_id(attempt.apple),
                        seal_blocked: attempt.seal_blocked,
                        exhausted: attempt.exhausted,
                    }),
                    held: contact.held.map(|held| HeldApple {
                        apple_id: apple_id(held.apple),
                        center_in_robot_m: world.apples[held.apple].center_in_robot_m,
                        offset_m: held.offset_m,
                        twist_at_seal_rad: held.twist_at_seal_rad,
                        detach_point_m: held.detach_point_m,
                        interference_travel_m: held.interference_travel_m,
                    }),
                }
            })
            .collect();
        state.robot = Some(RobotState {
            valves_open: robot.valves_commanded(),
            valve_opening: vacuum.valve_opening,
            source_mmh2o: vacuum.source_mmh2o,
            arm_mmh2o: vacuum.arm_mmh2o,
            arms,
        });
        state
    }

    /// Puts the robot's part of the state into `robot` (built on a world restored with
    /// [`Self::apply_apples`]): joints, valves, pressures, attempts and the apples on the cups.
    /// Nothing to do for a file without it. The values were checked by [`Self::load`].
    pub fn apply_robot(&self, robot: &mut SimRobot) -> Result<(), WorldStateError> {
        let Some(saved) = &self.robot else {
            return Ok(());
        };
        robot.set_valves(saved.valves_open);
        for arm in &saved.arms {
            robot.restore_arm(arm.arm, arm.joint_position, arm.joint_velocity)?;
        }
        let world = robot.world_mut();
        world.physics.vacuum = VacuumPlantState {
            valve_opening: saved.valve_opening,
            source_mmh2o: saved.source_mmh2o,
            arm_mmh2o: saved.arm_mmh2o,
        };
        let apple_count = world.apples.len();
        let index_of = |apple_id: u32| {
            let index = apple_id as usize;
            (index < apple_count).then_some(index)
        };
        for arm in &saved.arms {
            let attempt = arm.attempt.and_then(|attempt| {
                Some(Attempt {
                    apple: index_of(attempt.apple_id)?,
                    seal_blocked: attempt.seal_blocked,
                    exhausted: attempt.exhausted,
                })
            });
            let held = arm.held.and_then(|held| {
                let index = index_of(held.apple_id)?;
                let apple = &mut world.apples[index];
                debug_assert_eq!(apple.id, AppleId(held.apple_id));
                apple.state = AppleState::Attached {
                    arm: arm.arm,
                    detached: held.detach_point_m.is_some(),
                };
                apple.center_in_robot_m = held.center_in_robot_m;
                Some(Held {
                    apple: index,
                    offset_m: held.offset_m,
                    twist_at_seal_rad: held.twist_at_seal_rad,
                    detach_point_m: held.detach_point_m,
                    interference_travel_m: held.interference_travel_m,
                })
            });
            world.physics.arms[arm.arm.index()] = ArmContact { attempt, held };
        }
        Ok(())
    }

    /// The first value of the file that cannot be restored: a non-finite number, an apple id
    /// outside the world, an arm listed twice, an apple on two cups or both on a cup and off the
    /// tree.
    fn check(&self, path: &Path) -> Result<(), WorldStateError> {
        let invalid = |key: String, value: String, problem: &'static str| {
            Err(WorldStateError::Invalid {
                path: path.to_owned(),
                key,
                value,
                problem,
            })
        };
        let finite = |key: String, values: &[f64]| {
            if values.iter().all(|value| value.is_finite()) {
                Ok(())
            } else {
                invalid(key, format!("{values:?}"), "must be finite")
            }
        };
        let known = |key: String, apple_id: u32| {
            if (apple_id as usize) < self.apple_count {
                Ok(())
            } else {
                invalid(
                    key,
                    apple_id.to_string(),
                    "names an apple outside the world (apple_id >= apple_count)",
                )
            }
        };
        finite("trailer_m".to_owned(), &[self.trailer_m])?;
        finite("platform_m".to_owned(), &self.platform_m)?;
        for (i, entry) in self.off_tree.iter().enumerate() {
            known(format!("off_tree[{i}].apple_id"), entry.apple_id)?;
            finite(
                format!("off_tree[{i}].center_in_robot_m"),
                &entry.center_in_robot_m,
            )?;
        }
        let Some(robot) = &self.robot else {
            return Ok(());
        };
        finite("robot.valve_opening".to_owned(), &robot.valve_opening)?;
        finite("robot.source_mmh2o".to_owned(), &[robot.source_mmh2o])?;
        finite("robot.arm_mmh2o".to_owned(), &robot.arm_mmh2o)?;
        let mut held_ids = Vec::new();
        for (i, arm) in robot.arms.iter().enumerate() {
            let key = |field: &str| format!("robot.arms[{i}].{field}");
            if robot.arms[..i].iter().any(|other| other.arm == arm.arm) {
                invalid(key("arm"), format!("{:?}", arm.arm), "arm listed twice")?;
            }
            finite(key("joint_position"), &arm.joint_position)?;
            finite(key("joint_velocity"), &arm.joint_velocity)?;
            if let Some(attempt) = arm.attempt {
                known(key("attempt.apple_id"), attempt.apple_id)?;
            }
            if let Some(held) = arm.held {
                known(key("held.apple_id"), held.apple_id)?;
                finite(key("held.center_in_robot_m"), &held.center_in_robot_m)?;
                finite(key("held.offset_m"), &held.offset_m)?;
                finite(key("held.twist_at_seal_rad"), &[held.twist_at_seal_rad])?;
                finite(
                    key("held.detach_point_m"),
                    &held.detach_point_m.unwrap_or_default(),
                )?;
                finite(
                    key("held.interference_travel_m"),
                    &[held.interference_travel_m.unwrap_or_default()],
                )?;
                let off_tree = self.off_tree.iter().any(|e| e.apple_id == held.apple_id);
                if off_tree || held_ids.contains(&held.apple_id) {
                    invalid(
                        key("held.apple_id"),
                        held.apple_id.to_string(),
                        "apple also off the tree or on the other cup",
                    )?;
                }
                held_ids.push(held.apple_id);
            }
        }
        Ok(())
    }

    /// True when the state was taken of a world generated like `world`.
    pub fn fits(&self, world: &World) -> bool {
        self.world == world.scenario().name
            && self.seed == world.seed()
            && self.apple_count == world.apples().len()
    }

    /// Puts the harvested and dropped apples of the state into `world` (whose robot offset is
    /// already where the state says). Ids outside the world are skipped.
    pub fn apply_apples(&self, world: &mut World) {
        for entry in &self.off_tree {
            let Some(apple) = world.apples.get_mut(entry.apple_id as usize) else {
                tracing::warn!(
                    apple_id = entry.apple_id,
                    "world state names an unknown apple"
                );
                continue;
            };
            debug_assert_eq!(apple.id, AppleId(entry.apple_id));
            apple.state = match entry.state {
                OffTree::Harvested => AppleState::Harvested,
                OffTree::Dropped => AppleState::Dropped,
            };
            apple.center_in_robot_m = entry.center_in_robot_m;
        }
    }

    /// Reads a state file; `Ok(None)` when there is none.
    pub fn load(path: &Path) -> Result<Option<Self>, WorldStateError> {
        let text = match std::fs::read_to_string(path) {
            Ok(text) => text,
            Err(error) if error.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => {
                return Err(WorldStateError::Io {
                    path: path.to_owned(),
                    action: "read",
                    source,
                });
            }
        };
        let state: Self = toml::from_str(&text).map_err(|error| WorldStateError::Parse {
            path: path.to_owned(),
            message: error.to_string(),
        })?;
        state.check(path)?;
        Ok(Some(state))
    }

    /// Writes the state atomically: a temporary file in the same folder, synced, renamed.
    pub fn store(&self, path: &Path) -> Result<(), WorldStateError> {
        let text =
            toml::to_string(self).map_err(|error| WorldStateError::Encode(error.to_string()))?;
        let io = |action: &'static str| {
            let path = path.to_owned();
            move |source| WorldStateError::Io {
                path,
                action,
                source,
            }
        };
        if let Some(folder) = path.parent() {
            std::fs::create_dir_all(folder).map_err(io("create its folder"))?;
        }
        let mut temporary = path.as_os_str().to_owned();
        temporary.push(".tmp");
        let temporary = PathBuf::from(temporary);
        let mut file =
            std::fs::File::create(&temporary).map_err(io("create the temporary file"))?;
        file.write_all(text.as_bytes()).map_err(io("write"))?;
        file.sync_all().map_err(io("sync"))?;
        std::fs::rename(&temporary, path).map_err(io("rename the temporary file"))?;
        Ok(())
    }
}

/// Writes the state when it changed, at a bounded rate.
#[derive(Debug)]
pub struct WorldStatePersister {
    path: PathBuf,
    min_interval: Duration,
    saved: Option<WorldState>,
    pending: Option<WorldState>,
    last_write: Option<Instant>,
}

impl WorldStatePersister {
    /// Persists to `path`, at most once per `min_interval`; `saved` is what the file holds.
    pub fn new(path: PathBuf, min_interval: Duration, saved: Option<WorldState>) -> Self {
        Self {
            path,
            min_interval,
            saved,
            pending: None,
            last_write: None,
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn min_interval(&self) -> Duration {
        self.min_interval
    }

    /// Offers the current state; writes it if it differs from the file's and the last write
    /// is at least `min_interval` old (else keeps it for a later offer or [`Self::flush`]).
    pub fn offer(&mut self, state: WorldState, now: Instant) -> Result<bool, WorldStateError> {
        if self.saved.as_ref() == Some(&state) {
            self.pending = None;
            return Ok(false);
        }
        let due = self
            .last_write
            .is_none_or(|last| now.duration_since(last) >= self.min_interval);
        if !due {
            self.pending = Some(state);
            return Ok(false);
        }
        self.store_now(state, now)
    }

    /// Writes the state now, whatever the rate bound (an apple changed hands or the valves
    /// were commanded), unless the file already holds it.
    pub fn store_now(&mut self, state: WorldState, now: Instant) -> Result<bool, WorldStateError> {
        if self.saved.as_ref() == Some(&state) {
            self.pending = None;
            return Ok(false);
        }
        state.store(&self.path)?;
        tracing::debug!(path = %self.path.display(), off_tree = state.off_tree.len(), "world state saved");
        self.saved = Some(state);
        self.pending = None;
        self.last_write = Some(now);
        Ok(true)
    }

    /// Writes a state kept back by the rate bound.
    pub fn flush(&mut self) -> Result<(), WorldStateError> {
        if let Some(state) = self.pending.take() {
            state.store(&self.path)?;
            self.saved = Some(state);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Scenario;

    #[test]
    fn state_round_trips_and_is_rate_bounded() {
        let dir = std::env::temp_dir().join(format!("harvest-world-state-{}", std::process::id()));
        let path = dir.join("d.world.toml");
        let mut world =
            World::generate(&Scenario::preset("default").expect("preset"), 4).expect("world");
        world.apples[3].state = AppleState::Harvested;
        world.apples[5].state = AppleState::Dropped;
        let state = WorldState::of(&world, 1.5, [0.1, 0.2]);
        let mut persister = WorldStatePersister::new(path.clone(), Duration::from_secs(60), None);
        let start = Instant::now();
        assert!(persister.offer(state.clone(), start).expect("first write"));
        let mut later = state.clone();
        later.trailer_m = 2.0;
        assert!(!persister.offer(later.clone(), start).expect("held back"));
        assert_eq!(WorldState::load(&path).expect("load"), Some(state.clone()));
        persister.flush().expect("flush");
        let loaded = WorldState::load(&path).expect("load").expect("present");
        assert_eq!(loaded, later);
        let mut fresh =
            World::generate(&Scenario::preset("default").expect("preset"), 4).expect("world");
        assert!(loaded.fits(&fresh));
        loaded.apply_apples(&mut fresh);
        assert_eq!(fresh.apples()[3].state, AppleState::Harvested);
        assert_eq!(fresh.apples()[5].state, AppleState::Dropped);
        assert_eq!(fresh.apples()[4].state, AppleState::OnTree);
        std::fs::write(&path, "world = 3").expect("write garbage");
        assert!(matches!(
            WorldState::load(&path),
            Err(WorldStateError::Parse { .. })
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[cfg(test)]
mod restart_tests {
    //! A restart of the simulator in the middle of a pick: the state is stored, the robot
    //! dropped, a new one generated from the same scenario and seed and restored from the file.
    use super::*;
    use crate::physics::{ReleaseOutcome, StepInputs, WorldEvent};
    use crate::robot_test_moves::{move_to, nearest_apple, run, twist_and_pull_home};
    use crate::scenario::Scenario;
    use harvest_robot_model::kinematics::inverse;

    fn scenario() -> Scenario {
        Scenario::preset("ideal").expect("ideal")
    }

    /// Stores `robot`'s state, then builds the robot a restarted sim would from the file.
    fn restart(robot: &SimRobot, path: &Path) -> SimRobot {
        WorldState::of_robot(robot, 0.0, [0.0; 2])
            .store(path)
            .expect("store");
        let loaded = WorldState::load(path).expect("load").expect("present");
        let mut world = World::generate(&scenario(), 1).expect("world");
        assert!(loaded.fits(&world));
        loaded.apply_apples(&mut world);
        let mut restarted =
            SimRobot::from_world(world, crate::robot::SimRobotConfig::default()).expect("robot");
        loaded.apply_robot(&mut restarted).expect("apply");
        assert_eq!(
            WorldState::of_robot(&restarted, 0.0, [0.0; 2]),
            loaded,
            "the restarted robot is the stored one"
        );
        restarted
    }

    /// Restarts after the seal (apple on its stem) and after the detach (apple on the cup):
    /// the apple stays on the cup and is harvested once, on release over the dropping module.
    #[test]
    fn an_apple_on_a_cup_stays_on_it_across_restarts_and_is_harvested_once() {
        let dir = std::env::temp_dir().join(format!("harvest-restart-{}", std::process::id()));
        let path = dir.join("d.world.toml");
        let mut robot = SimRobot::new(&scenario(), 1).expect("robot");
        let params = *robot.arm_params(ArmId::Arm1);
        let apple = nearest_apple(&robot, ArmId::Arm1);
        let c = apple.center_in_robot_m;
        let q = inverse(&params, [c[0] - apple.radius_m, c[1], c[2]])
            .expect("reachable")
            .to_array();
        move_to(&mut robot, ArmId::Arm1, q, 2.0);
        robot.set_valves(StepInputs::valves_for_arms([true, false]));
        let events = run(&mut robot, 1.0);
        assert!(
            matches!(events.as_slice(), [WorldEvent::Attached { .. }]),
            "{events:?}"
        );

        // Restart while the cup holds the apple on its stem.
        let mut robot = restart(&robot, &path);
        assert_eq!(robot.world().held_apple(ArmId::Arm1), Some(apple.id));
        let events = twist_and_pull_home(&mut robot, ArmId::Arm1, q, params.home.to_array());
        assert_eq!(
            events,
            vec![WorldEvent::Detached {
                arm: ArmId::Arm1,
                apple: apple.id
            }]
        );

        // Restart with the detached apple on the cup, then release it.
        let mut robot = restart(&robot, &path);
        assert_eq!(
            robot.world().apples()[apple.id.0 as usize].state,
            AppleState::Attached {
                arm: ArmId::Arm1,
                detached: true
            }
        );
        robot.set_valves(StepInputs::valves_for_arms([false, false]));
        let events = run(&mut robot, 1.5);
        assert_eq!(
            events,
            vec![WorldEvent::Released {
                arm: ArmId::Arm1,
                apple: apple.id,
                outcome: ReleaseOutcome::Harvested
            }]
        );
        let robot = restart(&robot, &path);
        let harvested = robot
            .world()
            .apples()
            .iter()
            .filter(|a| a.state == AppleState::Harvested)
            .count();
        assert_eq!(harvested, 1);
        assert_eq!(robot.world().held_apple(ArmId::Arm1), None);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_state_that_cannot_be_restored_is_refused_naming_the_key() {
        let dir = std::env::temp_dir().join(format!("harvest-bad-state-{}", std::process::id()));
        let path = dir.join("d.world.toml");
        let robot = SimRobot::new(&scenario(), 1).expect("robot");
        let mut state = WorldState::of_robot(&robot, 0.0, [0.0; 2]);
        if let Some(saved) = state.robot.as_mut() {
            saved.arms[1].joint_position[2] = f64::NAN;
        }
        state.store(&path).expect("store");
        let error = WorldState::load(&path).expect_err("NaN joint");
        assert!(
            error.to_string().contains("robot.arms[1].joint_position"),
            "{error}"
        );
        let mut state = WorldState::of_robot(&robot, 0.0, [0.0; 2]);
        if let Some(saved) = state.robot.as_mut() {
            saved.arms[0].held = Some(HeldApple {
                apple_id: 10_000,
                center_in_robot_m: [1.0, 0.0, 0.2],
                offset_m: [0.0; 3],
                twist_at_seal_rad: 0.0,
                detach_point_m: None,
                interference_travel_m: None,
            });
        }
        state.store(&path).expect("store");
        let error = WorldState::load(&path).expect_err("unknown apple");
        assert!(
            error.to_string().contains("robot.arms[0].held.apple_id"),
            "{error}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
