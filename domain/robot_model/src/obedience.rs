//! The one rule by which a node obeys the operator's mode (`operator/mode`, published by the
//! executive): the arms, the vacuum supervisor and the evaluations all call [`obedience`](fn@obedience)
//! (the operator crate decides the mode; this crate sits under every node that obeys it).
//!
//! - New targets go out (vacuum supervisor) and are taken up (arm) only while the mode is
//!   harvesting, the row's stop cycle does not hold new approaches (`field_hold`) and the arm
//!   is enabled. An attempt under way runs to its end whatever the mode.
//! - Manual moves run only in manual mode, and only while the mode is fresh (heard within
//!   [`MODE_STALE_NS`]: the executive re-sends it at 10 Hz, so a silent executive stops them).
//! - **No mode heard means hold**, not harvest: a node that has not heard the executive
//!   dispatches and takes up nothing. A stack that runs without an executive (a bench
//!   profile, a test of the arms alone) says so explicitly ([`ModeSource::WithoutOperator`],
//!   the processes' `--without-operator` flag): then, until a mode is heard, it harvests with
//!   every arm. A mode heard always wins over the flag.
//!
//! The emergency stop is not part of this rule: it reaches every node on its own channel and
//! wins over every mode.

use harvest_ipc::payloads::{OperatorModeCode, OperatorModeState};

/// A manual move stops when `operator/mode` was not heard for this long (the executive
/// re-sends it at 10 Hz), ns.
pub const MODE_STALE_NS: u64 = 500_000_000;

/// Where the node expects its mode from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModeSource {
    /// The executive: until it is heard, hold.
    #[default]
    Executive,
    /// No executive runs (said explicitly by the launch file or the test): until a mode is
    /// heard, harvest with every arm.
    WithoutOperator,
}

/// What the node may do this tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Obedience {
    /// Per arm (index 0: arm 1): new targets are held (not dispatched, not taken up).
    pub targets_held: [bool; 2],
    /// Manual moves may start and go on.
    pub manual: bool,
}

impl Obedience {
    /// Everything held, no manual move.
    pub const HOLD: Self = Self {
        targets_held: [true; 2],
        manual: false,
    };
    /// Harvest with both arms, no manual move.
    pub const HARVEST: Self = Self {
        targets_held: [false; 2],
        manual: false,
    };
}

/// The rule (module documentation): `mode` is the newest `operator/mode` sample heard, if
/// any; `now_ns` is the node's clock (the mode's `capture_ns` is on the same clock).
pub fn obedience(mode: Option<&OperatorModeState>, source: ModeSource, now_ns: u64) -> Obedience {
    let Some(mode) = mode else {
        return match source {
            ModeSource::Executive => Obedience::HOLD,
            ModeSource::WithoutOperator => Obedience::HARVEST,
        };
    };
    let code = mode.mode_code();
    let harvesting = code == Some(OperatorModeCode::Harvesting) && mode.field_hold == 0;
    let fresh = now_ns.saturating_sub(mode.header.capture_ns) <= MODE_STALE_NS;
    Obedience {
        targets_held: mode.arms_enabled.map(|on| !harvesting || on == 0),
        manual: code == Some(OperatorModeCode::Manual) && fresh,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(code: OperatorModeCode, capture_ns: u64) -> OperatorModeState {
        let mut state = OperatorModeState {
            mode: code as u8,
            arms_enabled: [1, 1],
            ..OperatorModeState::default()
        };
        state.header.capture_ns = capture_ns;
        state
    }

    #[test]
    fn no_mode_heard_holds_unless_said_to_run_without_an_operator() {
        assert_eq!(obedience(None, ModeSource::Executive, 0), Obedience::HOLD);
        assert_eq!(
            obedience(None, ModeSource::WithoutOperator, 0),
            Obedience::HARVEST
        );
    }

    #[test]
    fn a_heard_mode_wins_over_the_flag() {
        for source in [ModeSource::Executive, ModeSource::WithoutOperator] {
            let paused = mode(OperatorModeCode::Paused, 0);
            assert_eq!(obedience(Some(&paused), source, 0), Obedience::HOLD);
            let harvesting = mode(OperatorModeCode::Harvesting, 0);
            assert_eq!(obedience(Some(&harvesting), source, 0), Obedience::HARVEST);
        }
    }

    #[test]
    fn the_field_hold_and_a_disabled_arm_hold_targets() {
        let mut harvesting = mode(OperatorModeCode::Harvesting, 0);
        harvesting.arms_enabled = [1, 0];
        let rule = obedience(Some(&harvesting), ModeSource::Executive, 0);
        assert_eq!(rule.targets_held, [false, true]);
        harvesting.field_hold = 1;
        let rule = obedience(Some(&harvesting), ModeSource::Executive, 0);
        assert_eq!(rule.targets_held, [true, true]);
    }

    #[test]
    fn manual_moves_need_a_fresh_manual_mode() {
        let manual = mode(OperatorModeCode::Manual, 1_000);
        let rule = obedience(Some(&manual), ModeSource::Executive, 1_000 + MODE_STALE_NS);
        assert_eq!(rule.targets_held, [true, true]);
        assert!(rule.manual);
        let stale = obedience(Some(&manual), ModeSource::Executive, 1_001 + MODE_STALE_NS);
        assert!(!stale.manual);
        let idle = mode(OperatorModeCode::Idle, 1_000);
        assert!(!obedience(Some(&idle), ModeSource::Executive, 1_000).manual);
    }
}
