//! The simulator's physics thread: the devices that must answer on time, as a real robot's
//! servo controller, valve board and platform controller do whatever its cameras are doing.
//!
//! On its own iceoryx2 node and wait set, never blocked by a render:
//! - every [`PHYSICS_PERIOD`] (200 Hz, the servo loop): the newest set-points of
//!   `hw/armN/servo` and command of `hw/valves/command` are applied, the [`SimRobot`] (servos,
//!   valves, vacuum, attach/detach) is stepped by the elapsed host time, encoder feedback goes
//!   out on `hw/armN/encoders` and the valve board's readings on `hw/valves/readings`, and the
//!   world's moving state is handed to the render thread ([`ThreadLink::publish_step`]);
//! - the platform controller at its feedback period (see [`crate::platform_device`]); the
//!   stages' positions (and the trailer's) move the robot in the world
//!   ([`crate::world_motion`]);
//! - the evaluation-only ground truth on `sim/ground_truth` at 10 Hz, and with it the world's
//!   state offered to the state file ([`crate::world_state`]), written at most every
//!   [`PhysicsThreadConfig::state_min_interval`] and once more when the thread stops; a step in
//!   which an apple changed hands or the valves were commanded writes it at once, before that
//!   step's readings go out.
//!
//! Simulated time advances with the host clock (each step's `dt` is the time since the last
//! one, clamped to [0.1 ms, 50 ms]), as it did when one thread served every device.

use crate::orchard::AppleState;
use crate::physics::ArmId;
use crate::platform_device::{PlatformDeviceConfig, PlatformDeviceError, PlatformDeviceServer};
use crate::robot::{SimRobot, SimRobotError};
use crate::row::RowPlatform;
use crate::thread_link::ThreadLink;
use crate::tractor_device::{TRACTOR_FEEDBACK_PERIOD, TractorDeviceServer, TractorMotion};
use crate::world_state::{WorldState, WorldStateError, WorldStatePersister};
use harvest_ipc::catalogue::{
    HW_ARM_ENCODERS, HW_ARM_SERVO, HW_VALVE_COMMAND, HW_VALVE_READINGS, SIM_GROUND_TRUTH,
};
use harvest_ipc::error::{IpcError, OpenChannelError};
use harvest_ipc::payloads::{
    EncoderFeedback, GroundTruth, ServoSetpoint, TrueApple, TrueAppleState, ValveBoardCommand,
    ValveBoardReadings,
};
use harvest_ipc::{Context, Domain, Flow, MonotonicClock, Publisher, Subscriber, Waiter};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Servo and physics period of the simulated robot (200 Hz).
pub const PHYSICS_PERIOD: Duration = Duration::from_millis(5);
/// Period of the evaluation-only ground truth.
pub const GROUND_TRUTH_PERIOD: Duration = Duration::from_millis(100);
/// Shortest and longest step, s: a late wake-up is caught up in one step of at most 50 ms.
const STEP_RANGE_S: (f64, f64) = (1e-4, 0.05);

const ARMS: [ArmId; 2] = [ArmId::Arm1, ArmId::Arm2];

/// Settings of the physics thread.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicsThreadConfig {
    /// Name of the thread's iceoryx2 node.
    pub node_name: String,
    /// The simulated platform controller.
    pub platform: PlatformDeviceConfig,
    /// Where the stages' stops put the robot in the row frame.
    pub row_platform: RowPlatform,
    /// Trailer position along the row at start, m.
    pub trailer_m: f64,
    /// The tractor's creep speed, m/s.
    pub tractor_speed_m_per_s: f64,
    /// End of the row (the tractor stops there), m.
    pub row_end_m: f64,
    /// Where the world's state is persisted (`None`: not persisted).
    pub state_file: Option<PathBuf>,
    /// Shortest interval between two writes of the state file.
    pub state_min_interval: Duration,
    /// What the state file held at start (the world was restored from it).
    pub saved_state: Option<WorldState>,
}

/// Why the physics thread stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum PhysicsThreadError {
    /// The transport (node, channel, send, receive, wait set) failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The simulated robot refused a step.
    #[error(transparent)]
    Robot(#[from] SimRobotError),
    /// The platform controller failed.
    #[error(transparent)]
    Platform(#[from] PlatformDeviceError),
    /// The world's state could not be persisted.
    #[error(transparent)]
    WorldState(#[from] WorldStateError),
}

harvest_ipc::from_ipc_errors!(PhysicsThreadError);

/// The physics thread's ports.
struct PhysicsPorts {
    servo_in: [Subscriber<ServoSetpoint>; 2],
    encoders_out: [Publisher<EncoderFeedback>; 2],
    valves_in: Subscriber<ValveBoardCommand>,
    valves_out: Publisher<ValveBoardReadings>,
    truth_out: Publisher<GroundTruth>,
}

impl PhysicsPorts {
    fn open(context: &Context) -> Result<Self, OpenChannelError> {
        Ok(Self {
            servo_in: [
                context.subscriber(HW_ARM_SERVO[0])?,
                context.subscriber(HW_ARM_SERVO[1])?,
            ],
            encoders_out: [
                context.publisher(HW_ARM_ENCODERS[0])?,
                context.publisher(HW_ARM_ENCODERS[1])?,
            ],
            valves_in: context.subscriber(HW_VALVE_COMMAND)?,
            valves_out: context.publisher(HW_VALVE_READINGS)?,
            truth_out: context.publisher(SIM_GROUND_TRUTH)?,
        })
    }

    /// Applies the newest commands the drivers sent, then advances the physics by `dt_s`.
    /// True when the step changed what must survive a restart at once: the valves were
    /// commanded or an apple changed hands.
    fn step_devices(&self, robot: &mut SimRobot, dt_s: f64) -> Result<bool, PhysicsThreadError> {
        for (arm, setpoints) in ARMS.into_iter().zip(&self.servo_in) {
            if let Some(setpoint) = setpoints.receive_latest()? {
                if setpoint.hold != 0 {
                    robot.hold(arm);
                } else if let Err(error) =
                    robot.set_servo_setpoint(arm, setpoint.joint_position, setpoint.joint_velocity)
                {
                    // A real servo controller refuses such a set-point and keeps its last order.
                    tracing::warn!(%error, "servo set-point refused");
                }
            }
        }
        let valves_before = robot.valves_commanded();
        if let Some(command) = self.valves_in.receive_latest()? {
            robot.set_valves(command.valve_open.map(|open| open != 0));
        }
        let events = robot.step(dt_s)?;
        for event in &events {
            tracing::debug!(?event, "world event");
        }
        Ok(!events.is_empty() || robot.valves_commanded() != valves_before)
    }

    /// Publishes what the devices report: encoders of both arms and the valve board's
    /// readings, stamped `capture_ns` (the time of the step).
    fn publish_device_state(
        &mut self,
        robot: &SimRobot,
        capture_ns: u64,
    ) -> Result<(), PhysicsThreadError> {
        for (arm, encoders) in ARMS.into_iter().zip(self.encoders_out.iter_mut()) {
            let (position, velocity) = robot.encoders(arm);
            encoders.publish_with(capture_ns, |feedback| {
                feedback.joint_position = position;
                feedback.joint_velocity = velocity;
                feedback.fault_bits = 0;
                feedback._reserved = [0; 7];
            })?;
        }
        let (open, in_transit, pressure_mmh2o) = robot.valve_readings();
        self.valves_out.publish_with(capture_ns, |readings| {
            readings.valve_open = open.map(u8::from);
            readings.valve_in_transit = in_transit.map(u8::from);
            readings.pressure_mmh2o = pressure_mmh2o;
            readings._reserved = [0; 4];
        })?;
        Ok(())
    }

    /// Publishes the true apples (evaluation only).
    fn publish_ground_truth(&mut self, robot: &SimRobot) -> Result<(), PhysicsThreadError> {
        let truth = robot.world().ground_truth();
        self.truth_out
            .publish_with(MonotonicClock::read_ns(), |message| {
                message.apples.clear();
                for apple in &truth.apples {
                    let state = match apple.state {
                        AppleState::OnTree => TrueAppleState::OnTree,
                        AppleState::Attached {
                            arm: ArmId::Arm1, ..
                        } => TrueAppleState::OnArm1,
                        AppleState::Attached {
                            arm: ArmId::Arm2, ..
                        } => TrueAppleState::OnArm2,
                        AppleState::Dropped => TrueAppleState::Dropped,
                        AppleState::Harvested => TrueAppleState::Harvested,
                    };
                    let entry = TrueApple {
                        apple_id: apple.id.0,
                        state: state.into(),
                        _reserved: [0; 3],
                        center_in_robot_m: apple.center_in_robot_m,
                        radius_m: apple.radius_m,
                    };
                    if message.apples.push(entry).is_err() {
                        break;
                    }
                }
            })?;
        Ok(())
    }
}

/// Runs the physics thread until SIGINT/SIGTERM or [`ThreadLink::request_stop`]; `robot` is
/// the world it owns from now on. Its node and ports are made here, on the calling thread
/// (iceoryx2 ports stay on the thread that made them).
pub fn run(
    domain: &Domain,
    config: &PhysicsThreadConfig,
    mut robot: SimRobot,
    link: &ThreadLink,
) -> Result<(), PhysicsThreadError> {
    let context = Context::new(domain, &config.node_name)?;
    let mut ports = PhysicsPorts::open(&context)?;
    let mut platform = PlatformDeviceServer::open(&context, config.platform)?;
    let waiter = Waiter::new()?;
    let physics_tick = waiter.attach_interval(PHYSICS_PERIOD)?;
    let platform_tick = waiter.attach_interval(platform.period())?;
    let truth_tick = waiter.attach_interval(GROUND_TRUTH_PERIOD)?;
    let mut tractor = TractorDeviceServer::open(
        &context,
        TractorMotion::new(
            config.tractor_speed_m_per_s,
            config.trailer_m,
            config.row_end_m,
        ),
    )?;
    let tractor_tick = waiter.attach_interval(TRACTOR_FEEDBACK_PERIOD)?;
    let mut persister = config.state_file.clone().map(|path| {
        WorldStatePersister::new(path, config.state_min_interval, config.saved_state.clone())
    });
    let robot_offset_m = |stage_m: [f64; 2], trailer_m: f64| {
        let [x, z] = config.row_platform.offset_m(stage_m);
        [x, trailer_m, z]
    };
    let mut last_step = Instant::now();
    let mut snapshots_skipped = 0u64;
    tracing::info!(node = %config.node_name, "physics thread running at 200 Hz");
    let end = waiter
        .run(|attachment| -> Result<Flow, PhysicsThreadError> {
            if link.stop_requested() {
                return Ok(Flow::Stop);
            }
            if attachment.has_event_from(&physics_tick) {
                let now = Instant::now();
                let dt_s = now
                    .duration_since(last_step)
                    .as_secs_f64()
                    .clamp(STEP_RANGE_S.0, STEP_RANGE_S.1);
                last_step = now;
                let changed_hands = ports.step_devices(&mut robot, dt_s)?;
                if changed_hands && let Some(persister) = persister.as_mut() {
                    // On disk before the stack sees this step's readings.
                    let state =
                        WorldState::of_robot(&robot, tractor.position_m(), platform.position_m());
                    persister.store_now(state, now)?;
                }
                let capture_ns = MonotonicClock::read_ns();
                ports.publish_device_state(&robot, capture_ns)?;
                if !link.publish_step(robot.world(), robot.time_ns(), capture_ns) {
                    snapshots_skipped += 1;
                }
            }
            if attachment.has_event_from(&tractor_tick) {
                tractor.tick()?;
            }
            if attachment.has_event_from(&platform_tick) || attachment.has_event_from(&tractor_tick)
            {
                if attachment.has_event_from(&platform_tick) {
                    platform.tick()?;
                }
                robot.world_mut().set_robot_offset_m(robot_offset_m(
                    platform.position_m(),
                    tractor.position_m(),
                ));
            }
            if attachment.has_event_from(&truth_tick) {
                ports.publish_ground_truth(&robot)?;
                if let Some(persister) = persister.as_mut() {
                    let state =
                        WorldState::of_robot(&robot, tractor.position_m(), platform.position_m());
                    persister.offer(state, Instant::now())?;
                }
            }
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten);
    if let Some(persister) = persister.as_mut() {
        let state = WorldState::of_robot(&robot, tractor.position_m(), platform.position_m());
        persister.store_now(state, Instant::now())?;
    }
    let end = end?;
    tracing::info!(
        ?end,
        physics_ticks = link.physics_ticks(),
        snapshots_skipped,
        sim_time_s = robot.time_s(),
        "physics thread stopped"
    );
    Ok(())
}
