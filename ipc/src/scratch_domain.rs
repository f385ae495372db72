//! A domain of its own for one test or benchmark run, which leaves nothing in /dev/shm once it
//! is dropped.
//!
//! [`Domain::unique`] names a fresh domain; every node created in it makes iceoryx2 create the
//! domain's node registry, which iceoryx2 keeps for good (see
//! [`remove_unused_registry`]). Without this guard each
//! test domain left one `*.global_mgmt` file behind, about 45 per run of the test suite.

use crate::cleanup::{RegistryRemoval, remove_dead_nodes, remove_unused_registry};
use crate::domain::Domain;

/// A [`Domain::unique`] domain that, when dropped, removes the resources of its dead nodes (the
/// processes a test killed) and then its node registry, if no node of it is left. A node still
/// alive (a child process that outlived the run) keeps everything in place: nothing in use is
/// ever removed.
#[derive(Debug)]
pub struct ScratchDomain(Domain);

impl ScratchDomain {
    /// A fresh domain named after `tag` (see [`Domain::unique`]).
    pub fn new(tag: &str) -> Self {
        Self(Domain::unique(tag))
    }

    /// The domain, for contexts opened in it.
    pub fn domain(&self) -> &Domain {
        &self.0
    }

    /// Removes the resources of the domain's dead nodes, then its node registry if no node of
    /// it is left (what dropping it does; call it to count the leftovers after it).
    pub fn remove_unused(&self) {
        if let Err(error) = remove_dead_nodes(&self.0) {
            tracing::warn!(%error, "scratch domain: dead nodes not removed");
        }
        match remove_unused_registry(&self.0) {
            Ok(RegistryRemoval::InUse { nodes }) => {
                tracing::warn!(domain = %self.0, nodes, "scratch domain still has nodes: its registry is kept");
            }
            Ok(RegistryRemoval::Removed | RegistryRemoval::Absent) => {}
            Err(error) => tracing::warn!(%error, "scratch domain: registry not removed"),
        }
    }
}

impl std::ops::Deref for ScratchDomain {
    type Target = Domain;

    fn deref(&self) -> &Domain {
        &self.0
    }
}

impl std::fmt::Display for ScratchDomain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl Drop for ScratchDomain {
    fn drop(&mut self) {
        self.remove_unused();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cleanup::leftover_files;

    fn registry_files(domain: &Domain) -> usize {
        let prefix = domain.file_prefix();
        std::fs::read_dir("/dev/shm")
            .map(|entries| {
                entries
                    .flatten()
                    .filter(|entry| {
                        let name = entry.file_name().to_string_lossy().into_owned();
                        name.starts_with(&prefix) && name.ends_with(".global_mgmt")
                    })
                    .count()
            })
            .unwrap_or(0)
    }

    #[test]
    fn a_dropped_scratch_domain_leaves_nothing_in_dev_shm() {
        let scratch = ScratchDomain::new("scrat");
        let domain = scratch.domain().clone();
        {
            let context = crate::Context::new(&scratch, "scratch-test").expect("node");
            let _publisher = context
                .publisher(crate::catalogue::EMERGENCY_STOP)
                .expect("publisher");
            assert_eq!(registry_files(&domain), 1, "the node created the registry");
        }
        drop(scratch);
        assert_eq!(registry_files(&domain), 0);
        assert!(leftover_files(&domain).is_empty());
    }

    #[test]
    fn a_scratch_domain_in_use_keeps_its_registry() {
        let scratch = ScratchDomain::new("scrin");
        let domain = scratch.domain().clone();
        let context = crate::Context::new(&domain, "scratch-test").expect("node");
        drop(scratch);
        assert_eq!(registry_files(&domain), 1, "a live node keeps the registry");
        drop(context);
        drop(ScratchDomain(domain.clone()));
        assert_eq!(registry_files(&domain), 0);
    }
}
