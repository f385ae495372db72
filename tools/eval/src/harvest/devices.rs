//! In-process device adapters: the hardware traits (`ArmServos`, `ValveBoard`) served by one
//! [`SimRobot`] shared on this thread, so the evaluation drives the nodes through the same device
//! interface the arm and vacuum processes use. Readings are stamped from the shared simulated
//! clock.

use std::cell::RefCell;
use std::rc::Rc;

use harvest_hw::arm_servos::{ArmServos, JOINT_COUNT, JointFeedback};
use harvest_hw::error_kind::{DeviceError, ErrorKind};
use harvest_hw::valve_board::{
    BoardFault, Heartbeat, PressureReadings, ValveBoard, ValveId, ValveState, ValveStates,
};
use harvest_ipc::{Clock, ManualClock};
use harvest_sim::physics::ArmId;
use harvest_sim::robot::SimRobot;

/// The simulated robot shared by the adapters of one episode.
pub type SharedRobot = Rc<RefCell<SimRobot>>;

/// Errors of the in-process devices.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InProcessDeviceError {
    /// The request was refused before reaching the device (NaN, out of limits, bad id).
    #[error("refused: {0}")]
    Refused(String),
    /// The simulated robot is borrowed elsewhere (a re-entrant call: a bug of the caller).
    #[error("simulated robot busy (re-entrant device call)")]
    Busy,
}

impl DeviceError for InProcessDeviceError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Refused(_) => ErrorKind::InvalidRequest,
            Self::Busy => ErrorKind::Other,
        }
    }
}

/// One arm's servos over the simulated robot.
#[derive(Debug, Clone)]
pub struct InProcessServos {
    robot: SharedRobot,
    arm: ArmId,
    clock: ManualClock,
}

impl InProcessServos {
    /// The servos of `arm`, stamping feedback with `clock`.
    pub fn new(robot: SharedRobot, arm: ArmId, clock: ManualClock) -> Self {
        Self { robot, arm, clock }
    }
}

impl ArmServos for InProcessServos {
    type Error = InProcessDeviceError;

    fn command(
        &mut self,
        position: [f64; JOINT_COUNT],
        velocity: [f64; JOINT_COUNT],
    ) -> Result<(), Self::Error> {
        let mut robot = self
            .robot
            .try_borrow_mut()
            .map_err(|_| InProcessDeviceError::Busy)?;
        robot
            .set_servo_setpoint(self.arm, position, velocity)
            .map_err(|e| InProcessDeviceError::Refused(e.to_string()))
    }

    fn hold(&mut self) -> Result<(), Self::Error> {
        self.robot
            .try_borrow_mut()
            .map_err(|_| InProcessDeviceError::Busy)?
            .hold(self.arm);
        Ok(())
    }

    fn feedback(&mut self) -> Result<Option<JointFeedback>, Self::Error> {
        let robot = self
            .robot
            .try_borrow()
            .map_err(|_| InProcessDeviceError::Busy)?;
        let (position, velocity) = robot.encoders(self.arm);
        Ok(Some(JointFeedback {
            capture_ns: self.clock.now_ns(),
            position,
            velocity,
            fault_bits: 0,
        }))
    }
}

/// The valve board over the simulated robot.
#[derive(Debug, Clone)]
pub struct InProcessValveBoard {
    robot: SharedRobot,
    clock: ManualClock,
}

impl InProcessValveBoard {
    /// The board, stamping nothing itself (pressures are read at `clock`'s now).
    pub fn new(robot: SharedRobot, clock: ManualClock) -> Self {
        Self { robot, clock }
    }
}

impl ValveBoard for InProcessValveBoard {
    type Error = InProcessDeviceError;

    fn set_valve(&mut self, valve: ValveId, open: bool) -> Result<(), Self::Error> {
        let index = valve
            .index()
            .ok_or_else(|| InProcessDeviceError::Refused(format!("{valve} does not exist")))?;
        let mut robot = self
            .robot
            .try_borrow_mut()
            .map_err(|_| InProcessDeviceError::Busy)?;
        let (mut commanded, _, _) = robot.valve_readings();
        commanded[index] = open;
        robot.set_valves(commanded);
        Ok(())
    }

    fn valve_states(&mut self) -> Result<ValveStates, Self::Error> {
        let robot = self
            .robot
            .try_borrow()
            .map_err(|_| InProcessDeviceError::Busy)?;
        let (open, in_transit, _) = robot.valve_readings();
        Ok(ValveStates(std::array::from_fn(|i| {
            match (open[i], in_transit[i]) {
                (true, false) => ValveState::Open,
                (false, false) => ValveState::Closed,
                (true, true) => ValveState::Opening,
                (false, true) => ValveState::Closing,
            }
        })))
    }

    fn pressures(&mut self) -> Result<PressureReadings, Self::Error> {
        let robot = self
            .robot
            .try_borrow()
            .map_err(|_| InProcessDeviceError::Busy)?;
        Ok(PressureReadings::from_array(robot.valve_readings().2))
    }

    fn close_all(&mut self) -> Result<(), Self::Error> {
        self.robot
            .try_borrow_mut()
            .map_err(|_| InProcessDeviceError::Busy)?
            .set_valves([false; 4]);
        Ok(())
    }

    fn ping(&mut self) -> Result<Heartbeat, Self::Error> {
        Ok(Heartbeat {
            board_uptime_ms: (self.clock.now_ns() / 1_000_000) as u32,
        })
    }

    fn take_faults(&mut self) -> Vec<BoardFault> {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harvest_sim::scenario::Scenario;

    fn robot() -> (SharedRobot, ManualClock) {
        let scenario = Scenario::preset("ideal").expect("ideal");
        let robot = SimRobot::new(&scenario, 1).expect("robot");
        (Rc::new(RefCell::new(robot)), ManualClock::starting_at(7))
    }

    #[test]
    fn servos_refuse_out_of_limit_set_points_and_report_feedback() {
        let (robot, clock) = robot();
        let mut servos = InProcessServos::new(robot.clone(), ArmId::Arm1, clock);
        let feedback = servos.feedback().expect("feedback").expect("sample");
        assert_eq!(feedback.capture_ns, 7);
        assert_eq!(feedback.position, [0.0; 4]);
        let error = servos
            .command([1.0, 0.0, 0.0, 0.0], [0.0; 4])
            .expect_err("D beyond 0.6 m");
        assert_eq!(error.kind(), ErrorKind::InvalidRequest);
        servos.command([0.01, 0.0, 0.0, 0.0], [0.0; 4]).expect("ok");
        servos.hold().expect("hold");
        assert!(robot.borrow().is_holding(ArmId::Arm1));
    }

    #[test]
    fn the_board_follows_the_trait_contract() {
        let (robot, clock) = robot();
        let mut board = InProcessValveBoard::new(robot.clone(), clock);
        let states = board.valve_states().expect("states");
        assert_eq!(
            states.0,
            [
                ValveState::Closed,
                ValveState::Open,
                ValveState::Closed,
                ValveState::Open
            ]
        );
        assert_eq!(
            board
                .set_valve(ValveId(5), true)
                .expect_err("no valve 5")
                .kind(),
            ErrorKind::InvalidRequest
        );
        board.set_valve(ValveId(1), true).expect("open 1");
        robot.borrow_mut().step(0.005).expect("step");
        assert_eq!(
            board.valve_states().expect("states").0[0],
            ValveState::Opening
        );
        board.close_all().expect("close all");
        robot.borrow_mut().step(0.005).expect("step");
        let states = board.valve_states().expect("states").0;
        // Valve 1 had moved 5 ms worth and is back at its end stop; the vents travel.
        assert_eq!(states[0], ValveState::Closed);
        assert_eq!(states[1], ValveState::Closing);
        assert_eq!(states[3], ValveState::Closing);
        assert!(board.pressures().expect("pressures").source_vacuum_mmh2o > 2000.0);
        assert!(board.take_faults().is_empty());
    }
}
