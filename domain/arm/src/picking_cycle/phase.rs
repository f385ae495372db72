//! [`CyclePhase`]: the phase of the picking cycle as the other arm and the processes see it.

use serde::{Deserialize, Serialize};

/// Phase of the picking cycle (section 3.3: Approach, Detach, Retract, Release; the paper's
/// Detach is our Attach, which includes the end-effector twist).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum CyclePhase {
    /// At rest (normally at the home/drop-off pose), ready for a target.
    Idle,
    /// Moving to the apple.
    Approach,
    /// At the apple: valve requested open, waiting for attachment, then twisting.
    Attach,
    /// Moving back to the drop-off pose (suction kept while an apple is held).
    Retract,
    /// At the drop-off pose with the valve closed, letting the apple fall.
    Release,
}
