//! The coordination policy as chosen on a command line (`harvest vacuum --policy`,
//! `harvest eval harvest --policy`).

use harvest_vacuum::policy::PolicyKind;
use serde::Serialize;

/// A vacuum coordination policy ([dual-arm sec. 4.2, Fig. 12]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize)]
pub enum PolicyArg {
    /// No coordination: the arms run strictly one after the other.
    Baseline,
    /// The 2023 version: parallel approaches, vacuum exclusive from attach to release.
    #[value(name = "2023")]
    V2023,
    /// The 2024 failure-aware policy (eq. 7-12).
    #[value(name = "2024")]
    V2024,
}

impl PolicyArg {
    /// The vacuum crate's policy kind.
    pub fn kind(self) -> PolicyKind {
        match self {
            Self::Baseline => PolicyKind::Baseline,
            Self::V2023 => PolicyKind::V2023,
            Self::V2024 => PolicyKind::V2024,
        }
    }
}
