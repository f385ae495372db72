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
    pub alive_nodes: usize,
}

/// Listing the domain's nodes failed.
#[derive(Debug, thiserror::Error)]
#[error("cannot list the iceoryx2 nodes of domain {domain:?}: {reason}")]
pub struct CleanupError {
    pub domain: String,
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

/// Files of `domain` that still exist in /dev/shm and under the iceoryx2 root directory (for
/// tests and `harvest clean --check`: after a clean shutdown this is empty).
///
/// Not counted: iceoryx2's per-prefix global management segment (`*.global_mgmt`, a few KiB),
/// which iceoryx2 keeps on purpose as the registry every node of the prefix attaches to; it
/// holds no channel data and is reused by the next run of the domain.
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
