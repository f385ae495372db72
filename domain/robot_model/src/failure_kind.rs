//! Why an attempt failed, as the vacuum supervisor infers it from the pressures and the safety
//! monitor judges it.

use serde::{Deserialize, Serialize};
use std::fmt;

/// How an attachment failed, as inferred from the pressure sensors ([dual-arm sec. 3.3] and
/// Table 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FailureKind {
    /// The valve was open for the whole attach window and no seal formed (a sealing failure, or
    /// a localization error that put the cup beside the apple).
    AttachFailed,
    /// A seal existed and was lost before the drop-off (the stem held the apple on the tree, or
    /// a branch knocked it off the cup during the retraction).
    Dropped,
}

impl fmt::Display for FailureKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FailureKind::AttachFailed => f.write_str("failed attachment"),
            FailureKind::Dropped => f.write_str("drop"),
        }
    }
}
