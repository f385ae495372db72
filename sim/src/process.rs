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
//! - the tractor's targets (`hw/tractor/command`) in, the trailer's position
//!   (`hw/tractor/feedback`) out at 20 Hz (see [`crate::tractor_device`]);
//! - the true apples on `sim/ground_truth` (evaluation only).
//!
//! With `--row FILE` the world is a whole orchard row ([`crate::row`]): several sections along
//! the row, the platform's stops in the row frame, the trailer's start. Moving the platform
//! moves the robot in the world ([`crate::world_motion`]).
//!
//! The world's state (harvested and dropped apples, trailer and platform positions, the arms'
//! joints, the apples on the cups, valves and vacuum) is kept in a state file ([`crate::world_state`], by default `<iceoryx2 root>/harvest-sim/<domain>.world.toml`)
//! and restored at start when it belongs to the same world (scenario or row, seed): a restart
//! of the sim process, `kill -9` included, continues the same world. `--fresh-world` ignores
//! (and then overwrites) it; `harvest sim` of another scenario or seed replaces it.
//!
//! Two threads serve the devices, as on the real robot where the servo controller does not stall
//! while a camera exposes:
//! - the physics thread ([`crate::physics_thread`]): servos, valve board, vacuum and contact
//!   physics at 200 Hz, the platform and the ground truth, never blocked by a render;
//! - the render thread ([`crate::render_thread`], the process's main thread and node): the ToF
//!   camera, the ALACS unit and the LiDAR, each rendered from the newest consistent snapshot of
//!   the moving world the physics thread hands over ([`crate::thread_link`]).
//!
//! Each thread has its own iceoryx2 node, ports and wait set; both end on SIGINT/SIGTERM, and
//! either one's end (an error included) ends the other. Simulated time advances with the host
//! clock. The world is generated from the seed as before; which physics step a camera frame
//! shows now depends on thread scheduling (it depended on host timing before too), while each
//! frame's depth noise is still a function of the world seed and the frame number.

use crate::alacs_device::AlacsDeviceConfig;
use crate::lidar_device::LidarDeviceConfig;
use crate::orchard::World;
use crate::physics_thread::{PhysicsThreadConfig, PhysicsThreadError};
use crate::platform_device::PlatformDeviceConfig;
use crate::render_thread::{CameraRenderer, RenderThreadConfig, RenderThreadError, RgbdCamera};
use crate::robot::SimRobot;
use crate::row::{RowPlatform, RowScenario};
use crate::scenario::Scenario;
use crate::thread_link::ThreadLink;
use crate::world_state::{WorldState, default_state_path};
use harvest_ipc::Domain;
use std::path::{Path, PathBuf};
use std::time::Duration;

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
    /// A row file (several tree sections along a row; see `harvest_sim::row`): replaces
    /// `--scenario` for the world, whose shared settings come from the row's first section.
    #[arg(long)]
    pub row: Option<PathBuf>,
    /// Where the world's state is persisted (default:
    /// `<iceoryx2 root>/harvest-sim/<domain>.world.toml`).
    #[arg(long)]
    pub state_file: Option<PathBuf>,
    /// Start from the generated world even when the state file holds one (it is overwritten).
    #[arg(long)]
    pub fresh_world: bool,
}

/// Why the simulator stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The scenario could not be loaded.
    #[error(transparent)]
    Scenario(#[from] crate::scenario::ScenarioError),
    /// The row file could not be loaded.
    #[error(transparent)]
    Row(#[from] crate::row::RowError),
    /// The world of the row or scenario could not be generated.
    #[error(transparent)]
    Orchard(#[from] crate::orchard::OrchardError),
    /// The state file could not be read.
    #[error(transparent)]
    WorldState(#[from] crate::world_state::WorldStateError),
    /// The camera renderer could not be built from the scenario.
    #[error(transparent)]
    Render(#[from] crate::render_rgbd::RenderError),
    /// The simulated robot could not be built from the scenario.
    #[error(transparent)]
    Robot(#[from] crate::robot::SimRobotError),
    /// The physics thread (servos, valves, vacuum, platform, ground truth) failed.
    #[error("sim physics thread: {0}")]
    Physics(#[source] PhysicsThreadError),
    /// The render thread (ToF camera, ALACS unit, LiDAR, heartbeat) failed.
    #[error("sim render thread: {0}")]
    RenderThread(#[source] RenderThreadError),
    /// The physics thread panicked (a bug); the render thread was stopped.
    #[error("sim physics thread panicked")]
    PhysicsPanicked,
    /// The OS refused to start the physics thread.
    #[error("cannot start the sim physics thread: {0}")]
    Spawn(#[source] std::io::Error),
    /// The camera rate is outside the supported range.
    #[error("camera rate must be between 0.1 and 120 Hz, got {0}")]
    BadRate(f64),
}

/// Settings of both threads.
#[derive(Debug, Clone, PartialEq)]
pub struct SimThreadsConfig {
    pub physics: PhysicsThreadConfig,
    pub render: RenderThreadConfig,
}

impl SimThreadsConfig {
    /// The threads of process `process_name`: the render thread's node carries the process
    /// name (its heartbeats), the physics thread's node `<process_name>-physics`.
    pub fn new(process_name: &str, camera_period: Duration, lidar: bool) -> Self {
        Self {
            physics: PhysicsThreadConfig {
                node_name: format!("{process_name}-physics"),
                platform: PlatformDeviceConfig::default(),
                row_platform: RowPlatform::default(),
                trailer_m: 0.0,
                tractor_speed_m_per_s: crate::row::RowTractor::default().speed_m_per_s,
                row_end_m: 0.0,
                state_file: None,
                state_min_interval: STATE_MIN_INTERVAL,
                saved_state: None,
            },
            render: RenderThreadConfig {
                node_name: process_name.to_owned(),
                camera_period,
                alacs: AlacsDeviceConfig::default(),
                lidar: lidar.then(LidarDeviceConfig::default),
            },
        }
    }
}

/// Shortest interval between two writes of the world's state file (a bound on the write rate;
/// at most this much of the world's history is lost to a `kill -9`).
pub const STATE_MIN_INTERVAL: Duration = Duration::from_millis(200);

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
    let (mut world, row_platform, tractor) = match &args.row {
        Some(path) => {
            let row = RowScenario::from_file(path)?;
            (
                World::generate_row(&row, args.seed)?,
                row.file.platform,
                row.file.tractor,
            )
        }
        None => {
            let scenario = load_scenario(&args.scenario)?;
            (
                World::generate(&scenario, args.seed)?,
                RowPlatform::default(),
                crate::row::RowTractor::default(),
            )
        }
    };
    let mut trailer_m = tractor.start_m;
    // The trailer may drive until the robot's y = 0 is at the end of the canopy.
    let row_end_m = world.scenario().canopy.y_range_m[1].max(trailer_m);
    let mut config = SimThreadsConfig::new(
        process_name,
        Duration::from_secs_f64(1.0 / args.camera_rate_hz),
        args.lidar,
    );
    config.physics.platform.travel = row_platform.travel();
    let state_file = args
        .state_file
        .clone()
        .unwrap_or_else(|| default_state_path(domain));
    let saved = if args.fresh_world {
        None
    } else {
        WorldState::load(&state_file)?
    };
    let restored = match saved {
        Some(state) if state.fits(&world) => {
            let platform_m = if config
                .physics
                .platform
                .travel
                .first_violation(state.platform_m)
                .is_none()
            {
                state.platform_m
            } else {
                tracing::warn!(platform_m = ?state.platform_m, "saved platform position outside the travel: stages homed");
                [0.0; 2]
            };
            trailer_m = state.trailer_m;
            config.physics.platform.start_m = platform_m;
            let [x, z] = row_platform.offset_m(platform_m);
            world.set_robot_offset_m([x, trailer_m, z]);
            state.apply_apples(&mut world);
            tracing::info!(
                path = %state_file.display(),
                off_tree = state.off_tree.len(),
                trailer_m,
                ?platform_m,
                "world restored from its state file"
            );
            Some(state)
        }
        Some(state) => {
            tracing::warn!(
                path = %state_file.display(),
                saved_world = %state.world,
                saved_seed = state.seed,
                "state file of another world: starting from the generated world (it will be replaced)"
            );
            None
        }
        None => {
            let [x, z] = row_platform.offset_m([0.0; 2]);
            world.set_robot_offset_m([x, trailer_m, z]);
            None
        }
    };
    config.physics.row_platform = row_platform;
    config.physics.trailer_m = trailer_m;
    config.physics.tractor_speed_m_per_s = tractor.speed_m_per_s;
    config.physics.row_end_m = row_end_m.max(trailer_m);
    config.physics.state_file = Some(state_file);
    config.physics.saved_state = restored;
    let mut robot = SimRobot::from_world(world, crate::robot::SimRobotConfig::default())?;
    if let Some(state) = &config.physics.saved_state {
        state.apply_robot(&mut robot)?;
    }
    let mut camera = RgbdCamera::new(&robot.world().scenario().camera)?;
    tracing::info!(
        scenario = %args.scenario,
        row = ?args.row,
        seed = args.seed,
        apples = robot.world().apples().len(),
        camera_rate_hz = args.camera_rate_hz,
        "simulated robot running"
    );
    let link = ThreadLink::new(robot.world());
    run_threads(domain, &config, robot, &mut camera, &link)?;
    tracing::info!("simulator stopped");
    Ok(())
}

/// Runs the physics thread on a new thread and the render thread on the calling one, from
/// `robot` (handed to the physics thread) and a copy of its world (kept by the render thread),
/// until SIGINT/SIGTERM or `link.request_stop()`. `link` must have been made from `robot`'s
/// world. When one thread fails the other is stopped and the failure returned (both failed:
/// the physics thread's, the render thread's is logged).
pub fn run_threads(
    domain: &Domain,
    config: &SimThreadsConfig,
    robot: SimRobot,
    camera: &mut impl CameraRenderer,
    link: &ThreadLink,
) -> Result<(), SimError> {
    let render_world = robot.world().clone();
    std::thread::scope(|scope| {
        let physics = std::thread::Builder::new()
            .name("sim-physics".to_owned())
            .spawn_scoped(scope, || {
                let _stop = link.stop_on_drop();
                crate::physics_thread::run(domain, &config.physics, robot, link)
            })
            .map_err(SimError::Spawn)?;
        let rendered = {
            let _stop = link.stop_on_drop();
            crate::render_thread::run(domain, &config.render, render_world, camera, link)
        };
        let physics = physics.join();
        match (physics, rendered) {
            (Ok(Ok(())), Ok(())) => Ok(()),
            (Ok(Err(physics)), rendered) => {
                if let Err(render) = rendered {
                    tracing::error!(error = %render, "sim render thread failed too");
                }
                Err(SimError::Physics(physics))
            }
            (Ok(Ok(())), Err(render)) => Err(SimError::RenderThread(render)),
            (Err(_panic), rendered) => {
                if let Err(render) = rendered {
                    tracing::error!(error = %render, "sim render thread failed too");
                }
                Err(SimError::PhysicsPanicked)
            }
        }
    })
}
