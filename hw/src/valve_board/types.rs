//! Plain data exchanged with a valve board: valve ids, valve states, pressure readings, board
//! heartbeats and board faults.
//!
//! Layout of the valve system ([dual-arm sec. 2.3, Fig. 3]): one vacuum source shared by
//! two arms; valves 1 and 2 serve arm 1, valves 3 and 4 serve arm 2; pressure sensors sit
//! inside arm 1, inside arm 2 and at the source.

use harvest_ipc::ArmId;
use std::fmt;

/// Number of butterfly valves on the board.
pub const VALVE_COUNT: usize = 4;

/// Number of pressure sensors on the board (arm 1, arm 2, source).
pub const PRESSURE_SENSOR_COUNT: usize = 3;

/// Peak vacuum the source can pull, in mmH2O below atmosphere (up to 2500
/// mmH2O at 360 m^3/h, [dual-arm sec. 2.3]).
pub const SOURCE_MAX_VACUUM_MMH2O: f32 = 2500.0;

/// Upper bound of a physically plausible reading, in mmH2O of vacuum: the source maximum plus
/// a margin for sensor gain error and noise.
pub const PLAUSIBLE_MAX_VACUUM_MMH2O: f32 = 3000.0;

/// Lower bound of a physically plausible reading, in mmH2O of vacuum. Slightly negative values
/// (a little above atmosphere) come from sensor offset and noise when a line is vented.
pub const PLAUSIBLE_MIN_VACUUM_MMH2O: f32 = -200.0;

/// Upper bound on the time a butterfly valve takes to travel between its end stops (actuation
/// under one second, [dual-arm sec. 2.3]).
pub const VALVE_ACTUATION_MAX_MS: u32 = 1000;

/// One of the four butterfly valves, numbered 1..=4 as on the board.
///
/// The field is public so ids coming from configuration, an operator or the wire can be carried
/// as they are; every [`super::ValveBoard`] implementation must refuse an id outside 1..=4 with
/// an `InvalidRequest` error before anything reaches the hardware. Use [`ValveId::new`] to
/// validate up front.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ValveId(pub u8);

impl ValveId {
    /// All four valid valves, in board order.
    pub const ALL: [ValveId; VALVE_COUNT] = [ValveId(1), ValveId(2), ValveId(3), ValveId(4)];

    /// The id if `number` is in 1..=4.
    pub fn new(number: u8) -> Option<ValveId> {
        (1..=VALVE_COUNT as u8)
            .contains(&number)
            .then_some(ValveId(number))
    }

    /// True if the id names a valve on the board (1..=4).
    pub fn is_valid(self) -> bool {
        ValveId::new(self.0).is_some()
    }

    /// Zero-based position in per-valve arrays, if valid.
    pub fn index(self) -> Option<usize> {
        self.is_valid().then(|| usize::from(self.0) - 1)
    }

    /// The arm this valve serves: valves 1-2 arm 1, valves 3-4 arm 2.
    pub fn arm(self) -> Option<ArmId> {
        match self.0 {
            1 | 2 => Some(ArmId::Arm1),
            3 | 4 => Some(ArmId::Arm2),
            _ => None,
        }
    }
}

impl fmt::Display for ValveId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "valve {}", self.0)
    }
}

/// The two valves serving `arm`, lower number first.
pub fn valves_of(arm: ArmId) -> [ValveId; 2] {
    match arm {
        ArmId::Arm1 => [ValveId(1), ValveId(2)],
        ArmId::Arm2 => [ValveId(3), ValveId(4)],
    }
}

/// Where a valve is, as last reported by the board.
///
/// A butterfly valve is driven by a small DC motor and takes up to
/// [`VALVE_ACTUATION_MAX_MS`] to travel; while it moves the board reports `Opening` or
/// `Closing`, and airflow (hence the arm pressure) is somewhere between the two end states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ValveState {
    /// At the closed end stop.
    Closed,
    /// At the open end stop.
    Open,
    /// Commanded open, not yet at the open end stop.
    Opening,
    /// Commanded closed, not yet at the closed end stop.
    Closing,
    /// The board gave up moving it (no end stop reached in time); position unknown. The board
    /// also sends a [`BoardFault::ValveStuck`] when it enters this state.
    Stuck,
}

impl ValveState {
    /// True while the valve is between end stops on its way to a commanded position.
    pub fn is_in_transit(self) -> bool {
        matches!(self, ValveState::Opening | ValveState::Closing)
    }

    /// True once the valve rests at the open end stop.
    pub fn is_open(self) -> bool {
        self == ValveState::Open
    }

    /// True once the valve rests at the closed end stop.
    pub fn is_closed(self) -> bool {
        self == ValveState::Closed
    }

    /// The state a valve reaches when commanded `open` (true) or closed (false).
    pub fn settled(open: bool) -> ValveState {
        if open {
            ValveState::Open
        } else {
            ValveState::Closed
        }
    }
}

/// The state of all four valves, indexed by valve number minus one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ValveStates(pub [ValveState; VALVE_COUNT]);

impl ValveStates {
    /// The state of one valve, `None` for an id outside 1..=4.
    pub fn get(&self, valve: ValveId) -> Option<ValveState> {
        valve.index().map(|i| self.0[i])
    }

    /// True if any valve is still moving.
    pub fn any_in_transit(&self) -> bool {
        self.0.iter().any(|s| s.is_in_transit())
    }

    /// Iterate `(valve, state)` pairs in board order.
    pub fn iter(&self) -> impl Iterator<Item = (ValveId, ValveState)> + '_ {
        ValveId::ALL.into_iter().zip(self.0.iter().copied())
    }
}

/// One of the three pressure sensors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PressureSensor {
    /// Inside arm 1's tube, behind its end-effector.
    Arm1,
    /// Inside arm 2's tube, behind its end-effector.
    Arm2,
    /// At the shared vacuum source.
    Source,
}

impl PressureSensor {
    /// Sensor number on the board (1 = arm 1, 2 = arm 2, 3 = source).
    pub fn number(self) -> u8 {
        match self {
            PressureSensor::Arm1 => 1,
            PressureSensor::Arm2 => 2,
            PressureSensor::Source => 3,
        }
    }

    /// The sensor with this board number.
    pub fn from_number(number: u8) -> Option<PressureSensor> {
        match number {
            1 => Some(PressureSensor::Arm1),
            2 => Some(PressureSensor::Arm2),
            3 => Some(PressureSensor::Source),
            _ => None,
        }
    }
}

/// One reading of the three pressure sensors, as vacuum in mmH2O (positive = below
/// atmosphere; 0 = vented; up to [`SOURCE_MAX_VACUUM_MMH2O`] at the source).
///
/// Readings are noisy (the board's 10-bit ADC quantises to a few mmH2O and turbulent flow
/// adds ripple); treat a single sample as an estimate and filter or threshold with margin
/// before inferring that an apple seals an end-effector.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PressureReadings {
    /// Vacuum inside arm 1, mmH2O.
    pub arm1_vacuum_mmh2o: f32,
    /// Vacuum inside arm 2, mmH2O.
    pub arm2_vacuum_mmh2o: f32,
    /// Vacuum at the shared source, mmH2O.
    pub source_vacuum_mmh2o: f32,
}

impl PressureReadings {
    /// The readings in the order used on the wire and in `harvest_ipc` payloads:
    /// `[arm 1, arm 2, source]`.
    pub fn to_array(self) -> [f32; PRESSURE_SENSOR_COUNT] {
        [
            self.arm1_vacuum_mmh2o,
            self.arm2_vacuum_mmh2o,
            self.source_vacuum_mmh2o,
        ]
    }

    /// Build from `[arm 1, arm 2, source]`.
    pub fn from_array(vacuum_mmh2o: [f32; PRESSURE_SENSOR_COUNT]) -> PressureReadings {
        PressureReadings {
            arm1_vacuum_mmh2o: vacuum_mmh2o[0],
            arm2_vacuum_mmh2o: vacuum_mmh2o[1],
            source_vacuum_mmh2o: vacuum_mmh2o[2],
        }
    }

    /// The reading of one sensor.
    pub fn get(&self, sensor: PressureSensor) -> f32 {
        match sensor {
            PressureSensor::Arm1 => self.arm1_vacuum_mmh2o,
            PressureSensor::Arm2 => self.arm2_vacuum_mmh2o,
            PressureSensor::Source => self.source_vacuum_mmh2o,
        }
    }

    /// True if every reading is finite and inside
    /// [`PLAUSIBLE_MIN_VACUUM_MMH2O`]..=[`PLAUSIBLE_MAX_VACUUM_MMH2O`].
    pub fn is_plausible(&self) -> bool {
        self.to_array().iter().all(|v| {
            v.is_finite() && (PLAUSIBLE_MIN_VACUUM_MMH2O..=PLAUSIBLE_MAX_VACUUM_MMH2O).contains(v)
        })
    }
}

/// What a board heartbeat returns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heartbeat {
    /// Milliseconds since the board's firmware started (an Arduino `millis()` counter: wraps
    /// after about 49.7 days; a value smaller than the previous one without a wrap means the
    /// board restarted and every valve went back to its power-on state).
    pub board_uptime_ms: u32,
}

/// A fault the board reports on its own, outside any request.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BoardFault {
    /// A valve did not reach its commanded end stop in time (motor, gear or gate jammed); it now
    /// reads [`ValveState::Stuck`] and further commands to it are refused.
    ValveStuck(ValveId),
    /// A pressure sensor reads out of its electrical range (disconnected or shorted).
    SensorFault(PressureSensor),
    /// The 12 V motor supply sagged below what the valve motors need.
    SupplyLow,
    /// The board restarted (power, brown-out or watchdog); all valves are back in their
    /// power-on state and the host's view of them is stale.
    BoardReset,
}

impl fmt::Display for BoardFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardFault::ValveStuck(v) => write!(f, "{v} stuck"),
            BoardFault::SensorFault(s) => write!(f, "pressure sensor {} fault", s.number()),
            BoardFault::SupplyLow => write!(f, "valve motor supply low"),
            BoardFault::BoardReset => write!(f, "board reset"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn valve_ids_map_to_arms_and_indices() {
        assert_eq!(ValveId::new(0), None);
        assert_eq!(ValveId::new(5), None);
        assert_eq!(ValveId::new(3), Some(ValveId(3)));
        assert_eq!(ValveId(1).arm(), Some(ArmId::Arm1));
        assert_eq!(ValveId(2).arm(), Some(ArmId::Arm1));
        assert_eq!(ValveId(3).arm(), Some(ArmId::Arm2));
        assert_eq!(ValveId(4).arm(), Some(ArmId::Arm2));
        assert_eq!(ValveId(9).arm(), None);
        assert_eq!(ValveId(4).index(), Some(3));
        assert_eq!(ValveId(0).index(), None);
        for arm in [ArmId::Arm1, ArmId::Arm2] {
            for v in valves_of(arm) {
                assert_eq!(v.arm(), Some(arm));
            }
        }
    }

    #[test]
    fn pressure_array_round_trip_and_plausibility() {
        let p = PressureReadings::from_array([1200.0, -3.0, 2410.0]);
        assert_eq!(p.to_array(), [1200.0, -3.0, 2410.0]);
        assert_eq!(p.get(PressureSensor::Source), 2410.0);
        assert!(p.is_plausible());
        assert!(!PressureReadings::from_array([f32::NAN, 0.0, 0.0]).is_plausible());
        assert!(!PressureReadings::from_array([0.0, 0.0, 9000.0]).is_plausible());
        for n in 1..=3 {
            let s = PressureSensor::from_number(n);
            assert_eq!(s.map(PressureSensor::number), Some(n));
        }
        assert_eq!(PressureSensor::from_number(4), None);
    }

    #[test]
    fn valve_states_lookup() {
        let s = ValveStates([
            ValveState::Closed,
            ValveState::Opening,
            ValveState::Open,
            ValveState::Stuck,
        ]);
        assert_eq!(s.get(ValveId(2)), Some(ValveState::Opening));
        assert_eq!(s.get(ValveId(5)), None);
        assert!(s.any_in_transit());
        assert_eq!(s.iter().count(), 4);
    }
}
