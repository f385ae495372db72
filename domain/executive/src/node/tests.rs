//! The executive node in process, through the robot's tick (`harvest_node::Schedule`).

use super::*;
use harvest_hw::ErrorKind;
use harvest_hw::platform::{PlatformPosition, PlatformTravel};
use harvest_hw::tractor::TractorPosition;
use harvest_ipc::payloads::{ArmPhase, OperatorRefusalCode};
use harvest_node::{Runner, RunnerConfig, Schedule};
use harvest_operator::Command;
use harvest_robot_model::ModeSource;
use harvest_robot_model::params::ArmParams;

const MS: u64 = 1_000_000;

#[derive(Debug, thiserror::Error)]
#[error("stages refused")]
struct Refused;

impl harvest_hw::DeviceError for Refused {
    fn kind(&self) -> ErrorKind {
        ErrorKind::InvalidRequest
    }
}

/// Stages that refuse every move (or not), and count their stops.
#[derive(Debug, Default)]
struct Stages {
    refuse: bool,
    stops: u32,
}

impl Platform for Stages {
    type Error = Refused;
    fn travel(&self) -> PlatformTravel {
        PlatformTravel::default()
    }
    fn move_to(&mut self, _: f64, _: f64) -> Result<(), Refused> {
        if self.refuse { Err(Refused) } else { Ok(()) }
    }
    fn stop(&mut self) -> Result<(), Refused> {
        self.stops += 1;
        Ok(())
    }
    fn position(&mut self) -> Result<PlatformPosition, Refused> {
        Ok(PlatformPosition::default())
    }
}

struct NoTractor;

impl Tractor for NoTractor {
    type Error = Refused;
    fn advance(&mut self, _: f64) -> Result<(), Refused> {
        Err(Refused)
    }
    fn stop(&mut self) -> Result<(), Refused> {
        Ok(())
    }
    fn position(&mut self) -> Result<TractorPosition, Refused> {
        Err(Refused)
    }
}

type TestNode = ExecutiveNode<Stages, NoTractor>;

struct Bench {
    schedule: Schedule,
    node: harvest_node::in_process::NodeHandle,
    token: ControlToken,
    request_id: u64,
}

fn arm_state(arm: usize) -> ArmState {
    let home = [ArmParams::arm1(), ArmParams::arm2()][arm].home.to_array();
    ArmState {
        arm_id: arm as u8 + 1,
        phase: ArmPhase::Idle.into(),
        joint_position: home,
        ..ArmState::default()
    }
}

impl Bench {
    fn new(initial_mode: OperatorModeCode, refuse: bool) -> Self {
        let token = ControlToken::generate().expect("token");
        let devices =
            ExecutiveDevices::new(Some(Stages { refuse, stops: 0 }), None::<NoTractor>, None);
        let config = ExecutiveNodeConfig {
            executive: ExecutiveConfig {
                initial_mode,
                ..ExecutiveConfig::default()
            },
            token: token.clone(),
            previous: None,
            row: None,
            travel_max_m: [0.5, 0.8],
        };
        let node = TestNode::new(config, &devices).expect("node");
        let runner = Runner::new(
            node,
            devices,
            RunnerConfig {
                max_read_failures: u32::MAX,
                mode_source: ModeSource::WithoutOperator,
            },
        );
        let mut schedule = Schedule::new(0);
        let node = schedule.add(runner, 5 * MS, 0);
        Self {
            schedule,
            node,
            token,
            request_id: 0,
        }
    }

    /// Publishes both arms' states and runs until `t_ms`.
    fn run_to(&mut self, t_ms: u64) {
        let now_ns = self.schedule.now_ns();
        for (arm, channel) in ARM_STATE.into_iter().enumerate() {
            let mut state = arm_state(arm);
            state.header.capture_ns = now_ns;
            self.schedule.bus_mut().publish(channel, state, now_ns);
        }
        self.schedule.run_until(t_ms * MS).expect("run");
    }

    fn send(&mut self, command: Command, token: &str) {
        self.request_id += 1;
        let message = command.to_message(self.request_id, 7, token, "test");
        let now_ns = self.schedule.now_ns();
        self.schedule
            .bus_mut()
            .publish(OPERATOR_COMMAND, message, now_ns);
    }

    fn latest<T: harvest_ipc::payload::Payload + Copy + 'static>(
        &mut self,
        channel: harvest_ipc::catalogue::Channel<T>,
    ) -> Option<T> {
        self.schedule.bus_mut().latest(channel)
    }

    fn runner(&self) -> &Runner<TestNode> {
        self.schedule.runner(self.node).expect("runner")
    }
}

#[test]
fn it_starts_once_the_arms_spoke_and_publishes_the_mode() {
    let mut b = Bench::new(OperatorModeCode::Harvesting, false);
    b.schedule.run_until(50 * MS).expect("run");
    assert!(
        b.latest(OPERATOR_MODE).is_none(),
        "no mode before the arms spoke"
    );
    b.run_to(60);
    let mode = b.latest(OPERATOR_MODE).expect("mode");
    assert_eq!(mode.mode_code(), Some(OperatorModeCode::Harvesting));
    assert_eq!(mode.platform_present, 1);
    assert_eq!(mode.field_hold, 0);
}

#[test]
fn a_stop_without_the_token_stops_and_the_stages_are_stopped_once() {
    let mut b = Bench::new(OperatorModeCode::Harvesting, false);
    b.run_to(20);
    b.send(Command::EmergencyStop, "not the token");
    b.run_to(25);
    let stop = b.latest(EMERGENCY_STOP).expect("stop");
    assert_eq!(stop.engaged, 1);
    let ack = b.latest(OPERATOR_ACK).expect("ack");
    assert_eq!((ack.accepted, ack.request_id), (1, 1));
    assert_eq!(ack.mode, OperatorModeCode::EmergencyStopped as u8);
    // The decision stops the stages at once (any manual motion ends); the runner reads the
    // stop back at the next tick and stops the devices again, once per engagement.
    let stops = |b: &Bench| b.runner().devices().platform().expect("stages").stops;
    assert_eq!(stops(&b), 1);
    b.run_to(100);
    assert_eq!(stops(&b), 2);
    // A release with a wrong token is refused; the stop stays.
    b.send(Command::Release, "not the token");
    b.run_to(110);
    let ack = b.latest(OPERATOR_ACK).expect("ack");
    assert_eq!(ack.accepted, 0);
    assert_eq!(b.latest(EMERGENCY_STOP).expect("stop").engaged, 1);
}

#[test]
fn a_platform_that_refuses_turns_the_acknowledgement_into_a_refusal() {
    for refuse in [false, true] {
        let mut b = Bench::new(OperatorModeCode::Idle, refuse);
        b.run_to(20);
        let token = b.token.as_str().to_owned();
        b.send(
            Command::PlatformMove {
                target_m: [0.1, 0.1],
            },
            &token,
        );
        b.run_to(30);
        let ack = b.latest(OPERATOR_ACK).expect("ack");
        if refuse {
            assert_eq!(ack.accepted, 0);
            assert_eq!(ack.refusal, OperatorRefusalCode::Device as u8);
            assert_eq!(
                b.runner().last_device_error(),
                Some(ErrorKind::InvalidRequest)
            );
        } else {
            assert_eq!(ack.accepted, 1, "{}", ack.reason.as_str());
        }
    }
}
