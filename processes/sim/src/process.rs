//! `harvest sim`: the simulated robot as hardware. Owns the world and serves the device
//! channels the drivers in the other processes talk to, as real devices would over USB/serial:
//! - the ToF camera's frames on `hw/camera/rgbd` at the camera's frame rate;
//! - each arm's servo set-points (`hw/armN/servo`) in, encoder feedback (`hw/armN/encoders`) out;
//! - the valve board's commands (`hw/valves/command`) in, readings (`hw/valves/readings`) out;
//! - the ALACS unit's commands (`hw/alacs/command`) in, its images (`hw/alacs/image`) out;
//! - the platform's targets (`hw/platform/command`) in, its positions (`hw/platform/feedback`)
//!   out at 50 Hz (see [`crate::platform_device`]);
//! - with `--lidar`, the solid-state LiDAR's point frames on `hw/lidar/points` at 10 Hz (see
//!   [`crate::lidar_device`]);
//! - the true apples on `sim/ground_truth` (evaluation only).
//!
//! The loop is one wait set: each device has an interval at its own period (the simulated
//! device's clock: physics and servos at 200 Hz, camera at its frame rate, ground truth at
//! 10 Hz) and the loop sleeps in between. Simulated time advances with the host clock.

use crate::alacs_device::{AlacsDeviceConfig, AlacsDeviceServer};
use crate::lidar_device::{LidarDeviceConfig, LidarDevicePort};
use crate::orchard::AppleState;
use crate::physics::Arm;
use crate::platform_device::{PlatformDeviceConfig, PlatformDeviceServer};
use crate::render_rgbd::RgbdRenderer;
use crate::robot::SimRobot;
use crate::scenario::Scenario;
use harvest_ipc::catalogue::{
    HW_ALACS_COMMAND, HW_ALACS_IMAGE, HW_ARM_ENCODERS, HW_ARM_SERVO, HW_CAMERA_RGBD,
    HW_VALVE_COMMAND, HW_VALVE_READINGS, SIM_GROUND_TRUTH,
};
use harvest_ipc::payloads::{
    EncoderFeedback, GroundTruth, ServoSetpoint, ValveBoardCommand, ValveBoardReadings,
};
use harvest_ipc::payloads::{ProcessRunState, TrueApple};
use harvest_ipc::{
    Context, Domain, Flow, HEARTBEAT_PERIOD, HealthReporter, MonotonicClock, Publisher, Subscriber,
    Waiter,
};
use std::path::Path;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, clap::Args)]
pub struct SimArgs {
    /// Scenario preset name (`default`, `ideal`, ...) or path to a scenario TOML file.
    #[arg(long, default_value = "default")]
    pub scenario: String,
    /// World seed (apples, leaves, noise, failures).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Frame rate of the simulated ToF camera.
    #[arg(long, default_value_t = 30.0)]
    pub camera_rate_hz: f64,
    /// Also simulate the solid-state LiDAR (Livox Mid-70) on `hw/lidar/points`.
    #[arg(long)]
    pub lidar: bool,
}

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    #[error(transparent)]
    Orchard(#[from] crate::orchard::OrchardError),
    #[error(transparent)]
    Render(#[from] crate::render_rgbd::RenderError),
    #[error(transparent)]
    Robot(#[from] crate::robot::SimRobotError),
    #[error(transparent)]
    Receive(#[from] harvest_ipc::error::ReceiveError),
    #[error(transparent)]
    Alacs(#[from] harvest_hw::alacs::AlacsError),
    #[error(transparent)]
    Platform(#[from] crate::platform_device::PlatformDeviceError),
    #[error(transparent)]
    Lidar(#[from] crate::lidar_device::LidarDeviceError),
    #[error(transparent)]
    Node(#[from] harvest_ipc::error::NodeError),
    #[error(transparent)]
    Channel(#[from] harvest_ipc::error::OpenChannelError),
    #[error(transparent)]
    Send(#[from] harvest_ipc::error::SendError),
    #[error(transparent)]
    Wait(#[from] harvest_ipc::error::WaitError),
    #[error("camera rate must be between 0.1 and 120 Hz, got {0}")]
    BadRate(f64),
}

/// Servo and physics rate of the simulated robot.
const PHYSICS_PERIOD: Duration = Duration::from_millis(5);
/// Rate of the evaluation-only ground truth.
const GROUND_TRUTH_PERIOD: Duration = Duration::from_millis(100);

const ARMS: [Arm; 2] = [Arm::One, Arm::Two];

/// Applies the newest commands the drivers sent, then advances the physics by `dt_s`.
fn step_devices(
    robot: &mut SimRobot,
    servo_in: &[Subscriber<ServoSetpoint>; 2],
    valves_in: &Subscriber<ValveBoardCommand>,
    dt_s: f64,
) -> Result<(), SimError> {
    for (arm, setpoints) in ARMS.into_iter().zip(servo_in) {
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
    if let Some(command) = valves_in.receive_latest()? {
        robot.set_valves(command.valve_open.map(|open| open != 0));
    }
    for event in robot.step(dt_s)? {
        tracing::debug!(?event, "world event");
    }
    Ok(())
}

/// Publishes what the devices report: encoders of both arms and the valve board's readings.
fn publish_device_state(
    robot: &SimRobot,
    encoders_out: &mut [Publisher<EncoderFeedback>; 2],
    valves_out: &mut Publisher<ValveBoardReadings>,
) -> Result<(), SimError> {
    let capture_ns = MonotonicClock::read_ns();
    for (arm, encoders) in ARMS.into_iter().zip(encoders_out.iter_mut()) {
        let (position, velocity) = robot.encoders(arm);
        encoders.publish_with(capture_ns, |feedback| {
            feedback.joint_position = position;
            feedback.joint_velocity = velocity;
            feedback.fault_bits = 0;
            feedback._reserved = [0; 7];
        })?;
    }
    let (open, in_transit, pressure_mmh2o) = robot.valve_readings();
    valves_out.publish_with(capture_ns, |readings| {
        readings.valve_open = open.map(u8::from);
        readings.valve_in_transit = in_transit.map(u8::from);
        readings.pressure_mmh2o = pressure_mmh2o;
        readings._reserved = [0; 4];
    })?;
    Ok(())
}

fn publish_ground_truth(
    robot: &SimRobot,
    truth_out: &mut Publisher<GroundTruth>,
) -> Result<(), SimError> {
    let truth = robot.world().ground_truth();
    truth_out.publish_with(MonotonicClock::read_ns(), |message| {
        message.apples.clear();
        for apple in &truth.apples {
            let state = match apple.state {
                AppleState::OnTree => 0,
                AppleState::Attached { arm: Arm::One, .. } => 1,
                AppleState::Attached { arm: Arm::Two, .. } => 2,
                AppleState::Dropped => 3,
                AppleState::Harvested => 4,
            };
            let entry = TrueApple {
                apple_id: apple.id.0,
                state,
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

/// Loads a scenario by preset name, or from a file when the argument is a path to one.
pub fn load_scenario(name_or_path: &str) -> Result<Scenario, crate::scenario::ScenarioError> {
    let path = Path::new(name_or_path);
    if name_or_path.ends_with(".toml") || path.is_file() {
        Scenario::from_file(path)
    } else {
        Scenario::preset(name_or_path)
    }
}

/// Runs the simulator until SIGINT/SIGTERM.
pub fn run(args: &SimArgs, domain: &Domain, process_name: &str) -> Result<(), SimError> {
    if !(0.1..=120.0).contains(&args.camera_rate_hz) {
        return Err(SimError::BadRate(args.camera_rate_hz));
    }
    let scenario = load_scenario(&args.scenario)?;
    let mut robot = SimRobot::new(&scenario, args.seed)?;
    let mut renderer = RgbdRenderer::new(&scenario.camera)?;
    let context = Context::new(domain, process_name)?;
    let mut camera_out = context.publisher(HW_CAMERA_RGBD)?;
    let mut alacs = AlacsDeviceServer::new(AlacsDeviceConfig::default())?;
    let alacs_commands = context.subscriber(HW_ALACS_COMMAND)?;
    let mut alacs_images = context.publisher(HW_ALACS_IMAGE)?;
    let servo_in = [
        context.subscriber(HW_ARM_SERVO[0])?,
        context.subscriber(HW_ARM_SERVO[1])?,
    ];
    let mut encoders_out = [
        context.publisher(HW_ARM_ENCODERS[0])?,
        context.publisher(HW_ARM_ENCODERS[1])?,
    ];
    let valves_in = context.subscriber(HW_VALVE_COMMAND)?;
    let mut valves_out = context.publisher(HW_VALVE_READINGS)?;
    let mut truth_out = context.publisher(SIM_GROUND_TRUTH)?;
    let mut health = HealthReporter::new(&context)?;
    let waiter = Waiter::new()?;
    let camera_tick = waiter.attach_interval(Duration::from_secs_f64(1.0 / args.camera_rate_hz))?;
    let heartbeat_tick = waiter.attach_interval(HEARTBEAT_PERIOD)?;
    let alacs_guard = waiter.attach_listener(alacs_commands.listener())?;
    let physics_tick = waiter.attach_interval(PHYSICS_PERIOD)?;
    let truth_tick = waiter.attach_interval(GROUND_TRUTH_PERIOD)?;
    let mut platform = PlatformDeviceServer::open(&context, PlatformDeviceConfig::default())?;
    let platform_tick = waiter.attach_interval(platform.period())?;
    let mut lidar = args
        .lidar
        .then(|| LidarDevicePort::open(&context, LidarDeviceConfig::default()))
        .transpose()?;
    let lidar_tick = lidar
        .as_ref()
        .map(|lidar| waiter.attach_interval(lidar.period()))
        .transpose()?;
    let mut last_physics = Instant::now();
    let color_from_depth = renderer
        .robot_from_color()
        .inverse()
        .compose(&renderer.robot_from_depth());
    tracing::info!(
        scenario = %args.scenario,
        seed = args.seed,
        apples = robot.world().apples().len(),
        camera_rate_hz = args.camera_rate_hz,
        "simulated robot running"
    );
    let mut render_ns_total = 0u64;
    waiter
        .run(|attachment| -> Result<Flow, SimError> {
            if attachment.has_event_from(&camera_tick) {
                let started = Instant::now();
                let capture_ns = MonotonicClock::read_ns();
                let mut frame = camera_out.loan()?;
                let frame_seq = camera_out.last_seq() + 1;
                renderer.render_color(robot.world(), &mut frame.rgb)?;
                renderer.render_depth(robot.world(), frame_seq, &mut frame.depth_mm)?;
                frame.meta.rgb_intrinsics = *renderer.color_intrinsics();
                frame.meta.depth_intrinsics = *renderer.depth_intrinsics();
                frame.meta.color_from_depth = color_from_depth;
                frame.meta.exposure_us = 10_000;
                frame.meta.flags = 0;
                frame.header.capture_ns = capture_ns;
                camera_out.send(frame)?;
                let render_ns = started.elapsed().as_nanos() as u64;
                render_ns_total += render_ns;
                tracing::trace!(frame_seq, render_ns, "frame rendered");
            }
            if attachment.has_event_from(&physics_tick) {
                let now = Instant::now();
                let dt_s = now
                    .duration_since(last_physics)
                    .as_secs_f64()
                    .clamp(1e-4, 0.05);
                last_physics = now;
                step_devices(&mut robot, &servo_in, &valves_in, dt_s)?;
                publish_device_state(&robot, &mut encoders_out, &mut valves_out)?;
            }
            if attachment.has_event_from(&alacs_guard) {
                // The ALACS device answers each command; a capture renders its camera image
                // (about 0.3 s here, during which the other simulated devices wait).
                while let Some(command) = alacs_commands.receive()? {
                    let mut image = alacs_images.loan()?;
                    alacs.handle(robot.world(), &command, &mut image);
                    alacs_images.send(image)?;
                }
            }
            if attachment.has_event_from(&platform_tick) {
                platform.tick()?;
            }
            if let (Some(lidar), Some(tick)) = (lidar.as_mut(), lidar_tick.as_ref())
                && attachment.has_event_from(tick)
            {
                lidar.tick(robot.world())?;
            }
            if attachment.has_event_from(&truth_tick) {
                publish_ground_truth(&robot, &mut truth_out)?;
            }
            if attachment.has_event_from(&heartbeat_tick) {
                let frames = camera_out.last_seq();
                let mean_render_us = render_ns_total
                    .checked_div(frames)
                    .map_or(0, |ns| ns / 1000);
                health.report(
                    ProcessRunState::Running,
                    frames,
                    "render_us",
                    mean_render_us,
                )?;
            }
            Ok(Flow::Continue)
        })
        .map_err(harvest_ipc::RunError::flatten)?;
    tracing::info!(frames = camera_out.last_seq(), "simulator stopped");
    Ok(())
}
