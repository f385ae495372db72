//! Removing what crashed processes left behind, through iceoryx2's API (never by deleting
//! files under /dev/shm by hand: that breaks live services).

use crate::context::Ipc;
use crate::domain::Domain;
use iceoryx2::node::{Node, NodeState, NodeView};
use iceoryx2::prelude::*;
use std::path::PathBuf;

/// What a cleanup pass did.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct CleanupReport {
    /// Names of dead nodes whose resources were removed.
    pub removed_nodes: Vec<String>,
    /// Dead nodes whose resources could not be removed, with the reason.
    pub failed_nodes: Vec<(String, String)>,
    /// Nodes of the domain that are alive (their resources kept).
    pub alive_nodes: usize,
}

/// Listing the domain's nodes failed.
#[derive(Debug, thiserror::Error)]
#[error("cannot list the iceoryx2 nodes of domain {domain:?}: {reason}")]
pub struct CleanupError {
    /// The domain whose nodes were listed.
    pub domain: String,
    /// iceoryx2's error, as text.
    pub reason: String,
}

/// Removes the stale resources of every dead node of `domain`.
pub fn remove_dead_nodes(domain: &Domain) -> Result<CleanupReport, CleanupError> {
    let config = domain.iceoryx2_config();
    let mut report = CleanupReport::default();
    Node::<Ipc>::list(&config, |state| {
        match state {
            NodeState::Dead(view) => {
                let name = view
                    .details()
                    .as_ref()
                    .map(|details| details.name().to_string())
                    .unwrap_or_else(|| format!("{:?}", view.id()));
                match view.try_remove_stale_resources() {
                    Ok(()) => report.removed_nodes.push(name),
                    Err(error) => report.failed_nodes.push((name, format!("{error:?}"))),
                }
            }
            NodeState::Alive(_) => report.alive_nodes += 1,
            NodeState::Inaccessible(_) | NodeState::Undefined(_) => {}
        }
        CallbackProgression::Continue
    })
    .map_err(|error| CleanupError {
        domain: domain.name().to_owned(),
        reason: format!("{error:?}"),
    })?;
    Ok(report)
}

/// Whether [`remove_unused_registry`] removed the domain's node registry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RegistryRemoval {
    /// Removed: no node of the domain was left.
    Removed,
    /// There was none (already removed, or the domain never ran).
    Absent,
    /// Kept: this many nodes of the domain exist (alive, dead with resources left, or another
    /// user's).
    InUse {
        /// Nodes of the domain found.
        nodes: usize,
    },
}

/// Removes the domain's node registry, iceoryx2's global management segment
/// (`/dev/shm/<prefix>…node.<version>.global_mgmt`, a node counter every node of the prefix
/// opens when it is created), when no node of the domain is left, alive or dead (remove dead
/// nodes first: [`remove_dead_nodes`]). iceoryx2 keeps that segment for good, so each domain would otherwise leave one
/// file in /dev/shm; the next node of the domain creates it again.
///
/// iceoryx2 requires that no process uses the domain while it is removed. Nodes are checked
/// just before; a process creating its first node in the same instant would keep the
/// segment it opened and the next one would create a new counter, which cannot give two nodes
/// one id (ids also hold the process id and the creation time).
pub fn remove_unused_registry(domain: &Domain) -> Result<RegistryRemoval, CleanupError> {
    let config = domain.iceoryx2_config();
    let mut in_use = 0;
    Node::<Ipc>::list(&config, |_| {
        in_use += 1;
        CallbackProgression::Continue
    })
    .map_err(|error| CleanupError {
        domain: domain.name().to_owned(),
        reason: format!("{error:?}"),
    })?;
    if in_use > 0 {
        return Ok(RegistryRemoval::InUse { nodes: in_use });
    }
    // SAFETY: no node of the domain exists (checked just above; see the doc comment for the
    // instant between the check and the removal).
    let removed = unsafe { iceoryx2::testing::remove_global_mgmt_segment::<Ipc>(&config) }
        .map_err(|error| CleanupError {
            domain: domain.name().to_owned(),
            reason: format!("removing the node registry: {error:?}"),
        })?;
    Ok(if removed {
        RegistryRemoval::Removed
    } else {
        RegistryRemoval::Absent
    })
}

/// Files of `domain` that still exist in /dev/shm and under the iceoryx2 root directory (for
/// tests and `harvest clean --check`: after a clean shutdown this is empty).
///
/// Not counted: iceoryx2's per-prefix global management segment (`*.global_mgmt`, a few KiB),
/// which iceoryx2 keeps on purpose as the registry every node of the prefix attaches to; it
/// holds no channel data and is reused by the next run of the domain. `harvest clean` removes
/// it once no node of the domain is left ([`remove_unused_registry`]).
pub fn leftover_files(domain: &Domain) -> Vec<PathBuf> {
    let prefix = domain.file_prefix();
    let config = domain.iceoryx2_config();
    let root = PathBuf::from(config.global.root_path().to_string());
    let mut found = Vec::new();
    let mut stack = vec![PathBuf::from("/dev/shm"), root];
    while let Some(dir) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.is_dir() && !path.starts_with("/dev/shm") {
                stack.push(path);
            } else if entry.file_name().to_string_lossy().starts_with(&prefix)
                && !entry
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".global_mgmt")
            {
                found.push(path);
            }
        }
    }
    found.sort();
    found
}
