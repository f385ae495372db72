//! The world's state on disk, so a restart of the sim process continues the same row: the same
//! apples (the world is regenerated from its scenario and seed), the same harvested and dropped
//! apples, the trailer and the platform where they stood.
//!
//! The file (TOML) is by default `<iceoryx2 root>/harvest-sim/<domain>.world.toml`
//! (`/tmp/iceoryx2/harvest-sim/` with the stack's iceoryx2 configuration, beside the domain's
//! `harvest up` lock; [`default_state_path`]). The physics thread offers the state after every
//! step; [`WorldStatePersister`] writes it when it changed, at most once per
//! [`WorldStatePersister::min_interval`] (and once more when the thread stops), to a temporary
//! file in the same folder, synced, then renamed over the old one: a reader (or a restart after
//! `kill -9`) sees either the old state or the new one, never a torn file. What happened in the
//! last interval before a crash is lost: at most the last interval's releases or moves.
//!
//! At start the sim loads the file when present and it belongs to the same world (scenario or
//! row name, seed, apple count); a file of another world is reported and replaced. An apple a
//! cup held when the sim stopped counts as dropped if its stem had let go (the vacuum is gone
//! after a restart) and springs back onto the tree otherwise.

use crate::orchard::{AppleId, AppleState, World};
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
        }
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
        toml::from_str(&text)
            .map(Some)
            .map_err(|error| WorldStateError::Parse {
                path: path.to_owned(),
                message: error.to_string(),
            })
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
