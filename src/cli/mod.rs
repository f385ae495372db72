//! The `harvest` command line.

pub mod logging;
mod up;

use anyhow::{Context as _, Result};
use clap::{Parser, Subcommand};
use harvest_ipc::Domain;
use harvest_ipc::cleanup::RegistryRemoval;
use std::process::ExitCode;

#[derive(Debug, Parser)]
#[command(
    name = "harvest",
    version,
    about = "Dual-arm apple-harvesting robot stack"
)]
pub struct Cli {
    /// Domain namespacing every channel (default: $HARVEST_DOMAIN, else "default").
    #[arg(long, global = true)]
    domain: Option<String>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the whole stack under the process supervisor (default: simulated robot).
    ///
    /// One stack per domain: refused while another `harvest up` (or a process of its stack)
    /// runs in the domain; the lock is `<iceoryx2 root>/harvest-up/<domain>.lock`
    /// (/tmp/iceoryx2/harvest-up/), holding the running supervisor's pid.
    Up(up::UpArgs),
    /// Simulated robot: the orchard world serving the hardware channels.
    #[cfg(feature = "sim-tools")]
    Sim(harvest_sim::process::SimArgs),
    /// Camera process: device frames -> camera/rgbd.
    Camera(harvest_camera::CameraArgs),
    /// Perception process: camera/rgbd -> perception/apples.
    Perception(harvest_perception_process::PerceptionArgs),
    /// Arm process: one arm's 200 Hz control loop (targets -> servos, state, valve requests).
    Arm(harvest_arm_process::ArmArgs),
    /// Vacuum process: valves, attachment inference, coordination policy and apple assignment.
    Vacuum(harvest_vacuum_process::process::VacuumArgs),
    /// Calibrate a sensor and print the comparison of methods.
    #[cfg(feature = "sim-tools")]
    #[command(subcommand)]
    Calibrate(CalibrateCommand),
    /// Benchmarks (latency of the transport and of the running stack).
    #[cfg(feature = "sim-tools")]
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Soak: the default stack in a domain of its own for --duration under random SIGKILLs,
    /// operator commands and bad inputs; reports restarts, RSS and descriptors per process,
    /// shared-memory files, recorder drops, harvested vs ground truth, safety violations, and
    /// exits 1 when a verdict fails.
    #[cfg(feature = "sim-tools")]
    Soak(harvest_bench::SoakArgs),
    /// The sending process of one benchmark case (started by `harvest bench ipc`).
    #[cfg(feature = "sim-tools")]
    #[command(name = "bench-peer", hide = true)]
    BenchPeer(harvest_bench::BenchPeerArgs),
    /// Evaluations against the simulator's ground truth.
    #[cfg(feature = "sim-tools")]
    #[command(subcommand)]
    Eval(EvalCommand),
    /// Training data rendered by the simulator with exact labels.
    #[cfg(feature = "sim-tools")]
    #[command(subcommand)]
    Dataset(DatasetCommand),
    /// Laser process: answers scan requests with the ALACS unit.
    Laser(harvest_laser_process::LaserArgs),
    /// LiDAR process: integrated point clouds of the solid-state LiDAR -> lidar/points.
    Lidar(harvest_lidar_process::LidarArgs),
    /// Recorder process: every channel of the domain -> MCAP files.
    Recorder(Box<harvest_recorder::RecorderArgs>),
    /// Foxglove bridge: the stack's channels, mapped to Foxglove's schemas, on a WebSocket
    /// server (ws://127.0.0.1:8765) for Foxglove or Lichtblick.
    Foxglove(harvest_foxglove::FoxgloveArgs),
    /// Republish a recording into the channels at recorded timing; with `--check`, re-run
    /// this build's perception, arms and vacuum supervisor on it and compare with what was
    /// recorded.
    Replay(ReplayCommand),
    /// Recording tools: info, cat, export, clips, recover.
    Rec {
        #[command(subcommand)]
        command: harvest_rec::RecCommand,
    },
    /// Remove stale iceoryx2 resources of dead processes in the domain, and the domain's node
    /// registry in /dev/shm once no process of the domain is left.
    Clean {
        /// Only list this domain's files still present; exit 1 if any.
        #[arg(long)]
        check: bool,
    },
    /// Safety monitor: judge the stack's channels live, or a recording (`--recording`);
    /// prints violations as found, exits non-zero if any.
    Monitor(harvest_monitor::MonitorArgs),
    /// List the channel catalogue.
    Channels {
        /// Print the schema of this channel's payload instead, as recordings store it.
        #[arg(long, value_name = "TOPIC")]
        schema: Option<String>,
    },
    /// Executive: the operator's mode machine, the emergency stop's one writer, manual moves,
    /// the platform.
    Executive(harvest_executive::ExecutiveArgs),
    /// Operator commands from the terminal: status, start, pause, resume, stop, estop,
    /// release, home, arm N enable|disable, jog, drop-off, platform, mark.
    Ctl {
        #[command(flatten)]
        link: harvest_remote_process::link_session::LinkArgs,
        #[command(flatten)]
        args: harvest_executive::ctl::CtlArgs,
    },
    /// Remote link (on the robot): chosen channels to Zenoh under `harvest/v1/<robot>/...`, at
    /// their rates and priorities; operator commands from the station answered by the
    /// executive. Off the network unless given --listen/--connect or --link FILE.
    Remote(harvest_remote_process::RemoteArgs),
    /// Fleet page (on the station): every robot seen on the link with its mode, e-stop,
    /// harvest and alarms (http://127.0.0.1:8090 by default).
    Fleet(harvest_remote_process::fleet::FleetArgs),
    /// Operator console: the robot's camera view, status and control panels in a browser
    /// (http://127.0.0.1:8080 by default). With --remote ROBOT, on the station: the same page
    /// fed over the remote link (--connect/--link as for `harvest ctl --remote`).
    Console {
        #[command(flatten)]
        args: harvest_console::ConsoleArgs,
        /// Serve this robot's console here, fed over the remote link (the station's side).
        #[arg(long, value_name = "ROBOT")]
        remote: Option<String>,
        /// With --remote: the link's settings (TOML, as for `harvest ctl --remote`).
        #[arg(long = "link", value_name = "FILE", requires = "remote")]
        link_file: Option<std::path::PathBuf>,
        /// With --remote: an endpoint to connect to, added to the file's
        /// (`tcp/127.0.0.1:7447`).
        #[arg(long = "connect", value_name = "ENDPOINT", requires = "remote")]
        connect: Vec<String>,
    },
}

#[cfg(feature = "sim-tools")]
#[derive(Debug, Subcommand)]
enum CalibrateCommand {
    /// ALACS laser-camera extrinsics (alpha, L0, beta): Algorithm 1 and the Table 1 comparison.
    Laser(harvest_calibrate::CalibrateLaserArgs),
    /// LiDAR-camera extrinsic (target-based, eq. 3) from generated checkerboard scenes or a
    /// recorded data set (--data DIR): the Table I report (average and normalized reprojection
    /// error).
    LidarCamera(harvest_calibrate::CalibrateLidarCameraArgs),
}

#[cfg(feature = "sim-tools")]
#[derive(Debug, Subcommand)]
enum BenchCommand {
    /// One-way latency between separate processes: our layer vs raw iceoryx2 vs a copying
    /// Unix socket, 64 B to 16 MB, event-driven and busy-poll wake-ups.
    Ipc(harvest_bench::BenchIpcArgs),
    /// End-to-end latency in a running stack (simulated robot): capture -> camera ->
    /// perception -> arm target -> arm command per hop, and the arm control loop's jitter.
    Pipeline(harvest_bench::BenchPipelineArgs),
    /// Perception's detectors' latency per 1920x1080 frame: ONNX models (CPU provider) beside the
    /// colour segmentation, on one simulated frame.
    Detector(harvest_bench::BenchDetectorArgs),
    /// The Livox Mid-70 driver (`harvest lidar --device livox`) against the fake device on
    /// loopback: rate, lost packets, CPU, latency, silence report and reconnection.
    LidarLivox(harvest_bench::BenchLidarLivoxArgs),
    /// The GigE Vision camera driver (`harvest camera --device gige`) against Aravis's fake
    /// camera on loopback: frame rate, lost frames, camera timestamp -> `camera/rgbd` latency,
    /// CPU.
    CameraGige(harvest_bench::BenchCameraGigeArgs),
    /// The recorder's camera video: H.264 encoding ms per 1920x1080 frame on one core, decoding,
    /// bytes per frame, and the depth image's lossless PNG.
    Video(harvest_bench::BenchVideoArgs),
    /// The operator console (`harvest console`) in a running stack: CPU per push viewer,
    /// capture to the image in Chromium, e-stop click to both arms braked under load (viewers
    /// and half-open connections), memory with viewers coming and going.
    Console(harvest_bench::BenchConsoleArgs),
    /// The remote link with several robots (replayed domains) and one station: camera capture
    /// to the station's screen, bandwidth per robot, command round trip, the station's CPU
    /// per robot.
    Remote(harvest_bench::BenchRemoteArgs),
    /// The station of `harvest bench remote` (started by it).
    #[command(hide = true)]
    RemoteStation(harvest_bench::BenchRemoteStationArgs),
}

#[cfg(feature = "sim-tools")]
#[derive(Debug, Subcommand)]
enum DatasetCommand {
    /// Domain-randomised colour frames resampled as the ONNX detector sees them, with YOLO
    /// labels and per-apple visibility (for tools/detector_training/).
    Detector(harvest_eval::detector_dataset::DetectorDatasetArgs),
}

#[cfg(feature = "sim-tools")]
#[derive(Debug, Subcommand)]
enum EvalCommand {
    /// Detection precision/recall, 3D error and processing time per estimator, on rendered frames.
    Perception(harvest_eval::EvalPerceptionArgs),
    /// Complete harvests in the simulator (arm, vacuum and assignment logic under a simulated
    /// clock): cycle times per apple and per attempt, success, per-apple events.
    Harvest(harvest_eval::harvest::EvalHarvestArgs),
    /// Rows stop by stop under a simulated clock with perception in the loop (the executive's
    /// stop-and-go cycle, platform positioning): [dual-arm Tables 2-3], single vs
    /// dual arm.
    Row(harvest_eval::row::EvalRowArgs),
    /// Laser refinement of ToF apple positions: error before/after and the time a scan costs.
    Laser(harvest_eval::laser::EvalLaserArgs),
    /// Fused LiDAR-camera vs ToF fruit localization repeatability per distance (Table III
    /// style) and the fusion time.
    Lidar(harvest_eval::lidar::EvalLidarArgs),
}

impl Cli {
    /// The name this process runs under: given by the supervisor, else the subcommand's name.
    pub fn process_name(&self) -> String {
        if let Ok(name) = std::env::var(harvest_supervisor::child::PROCESS_NAME_ENV)
            && !name.is_empty()
        {
            return name;
        }
        match &self.command {
            Command::Up(_) => "supervisor",
            #[cfg(feature = "sim-tools")]
            Command::Sim(_) => "sim",
            Command::Camera(_) => "camera",
            Command::Perception(_) => "perception",
            Command::Arm(args) => {
                if args.id == 1 {
                    "arm1"
                } else {
                    "arm2"
                }
            }
            Command::Vacuum(_) => "vacuum",
            #[cfg(feature = "sim-tools")]
            Command::Calibrate(_) => "calibrate",
            #[cfg(feature = "sim-tools")]
            Command::Bench(_) => "bench",
            #[cfg(feature = "sim-tools")]
            Command::Eval(_) => "eval",
            #[cfg(feature = "sim-tools")]
            Command::Dataset(_) => "dataset",
            #[cfg(feature = "sim-tools")]
            Command::Soak(_) => "soak",
            Command::Recorder(_) => "recorder",
            Command::Foxglove(_) => "foxglove",
            Command::Laser(_) => "laser",
            Command::Lidar(_) => "lidar",
            Command::Replay(_) => "replay",
            Command::Rec { .. } => "rec",
            #[cfg(feature = "sim-tools")]
            Command::BenchPeer(_) => "bench-peer",
            Command::Clean { .. } => "clean",
            Command::Monitor(_) => "monitor",
            Command::Channels { .. } => "channels",
            Command::Executive(_) => "executive",
            Command::Ctl { .. } => "ctl",
            Command::Remote(_) => "remote",
            Command::Fleet(_) => "fleet",
            Command::Console { .. } => "console",
        }
        .to_owned()
    }

    pub fn run(self, process_name: &str) -> Result<ExitCode> {
        let domain = Domain::from_flag_or_env(self.domain.as_deref())?;
        match self.command {
            Command::Up(args) => up::up(args, domain),
            Command::Arm(args) => {
                harvest_arm_process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("arm process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Vacuum(args) => {
                harvest_vacuum_process::process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("vacuum process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Sim(args) => {
                harvest_sim::process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("sim process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Perception(args) => {
                harvest_perception_process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("perception process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Camera(args) => {
                harvest_camera::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("camera process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Calibrate(CalibrateCommand::Laser(args)) => {
                harvest_calibrate::run_calibrate_laser(&args).context("laser calibration")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::Ipc(args)) => {
                let report = harvest_bench::run_bench_ipc(&args).context("ipc benchmark")?;
                print!("{}", report.table());
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::Video(args)) => {
                harvest_bench::run_bench_video(&args).context("video benchmark")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::Detector(args)) => {
                harvest_bench::run_bench_detector(&args).context("detector benchmark")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::CameraGige(args)) => {
                harvest_bench::run_bench_camera_gige(&args).context("camera-gige benchmark")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::LidarLivox(args)) => {
                harvest_bench::run_bench_lidar_livox(&args).context("lidar-livox benchmark")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::Console(args)) => {
                let report =
                    harvest_bench::run_bench_console(&args).context("console benchmark")?;
                print!("{}", report.render());
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::Remote(args)) => {
                harvest_bench::run_bench_remote(&args).context("remote benchmark")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::RemoteStation(args)) => {
                harvest_bench::run_bench_remote_station(&args)
                    .context("remote benchmark station")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Bench(BenchCommand::Pipeline(args)) => {
                let report = harvest_bench::run_bench_pipeline(&args, &domain)
                    .context("pipeline benchmark")?;
                print!("{}", report.table());
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Soak(args) => {
                let report = harvest_bench::run_soak(&args).context("soak")?;
                print!("{}", report.render());
                Ok(if report.passed() {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::FAILURE
                })
            }
            #[cfg(feature = "sim-tools")]
            Command::Eval(EvalCommand::Perception(args)) => {
                harvest_eval::run_eval_perception(&args).context("perception evaluation")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Laser(args) => {
                harvest_laser_process::process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("laser process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Dataset(DatasetCommand::Detector(args)) => {
                let summary = harvest_eval::detector_dataset::write_dataset(&args)
                    .with_context(|| format!("detector data set in {}", args.out.display()))?;
                println!(
                    "{} images, {} labelled apples, {} barely visible (listed, not labelled) in {}",
                    summary.images,
                    summary.labelled_apples,
                    summary.ignored_apples,
                    args.out.display()
                );
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Eval(EvalCommand::Harvest(args)) => {
                let report =
                    harvest_eval::harvest::run_eval_harvest(&args).context("harvest evaluation")?;
                print!("{}", report.render_text());
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Eval(EvalCommand::Row(args)) => {
                let report = harvest_eval::row::run_eval_row(&args).context("row evaluation")?;
                print!("{}", report.render_text());
                Ok(ExitCode::SUCCESS)
            }
            Command::Lidar(args) => {
                harvest_lidar_process::process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("lidar process", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Calibrate(CalibrateCommand::LidarCamera(args)) => {
                harvest_calibrate::run_calibrate_lidar_camera(&args)
                    .context("lidar-camera calibration")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Eval(EvalCommand::Lidar(args)) => {
                harvest_eval::lidar::run_eval_lidar(&args).context("lidar evaluation")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::Eval(EvalCommand::Laser(args)) => {
                harvest_eval::laser::run_eval_laser(&args).context("laser evaluation")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Recorder(args) => {
                harvest_recorder::run_recorder(&args, &domain, process_name)
                    .context("recorder process")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Foxglove(args) => {
                harvest_foxglove::run(&args, &domain, process_name).context("foxglove bridge")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Replay(command) if command.check => run_check(&command),
            Command::Replay(command) => {
                let report = harvest_rec::run_replay(&command.replay, &domain).context("replay")?;
                eprint!("{report}");
                Ok(ExitCode::SUCCESS)
            }
            Command::Rec { command } => {
                harvest_rec::run_rec(&command).context("harvest rec")?;
                Ok(ExitCode::SUCCESS)
            }
            #[cfg(feature = "sim-tools")]
            Command::BenchPeer(args) => {
                harvest_bench::run_bench_peer(&args).context("benchmark peer")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Monitor(args) => {
                let report = harvest_monitor::run_monitor(&args, &domain, process_name)
                    .context("safety monitor")?;
                print!("{}", report.render());
                Ok(if report.violations.is_empty() {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::FAILURE
                })
            }
            Command::Clean { check } => clean(&domain, check),
            Command::Executive(args) => {
                harvest_executive::run(&args, &domain, process_name).context("executive")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Ctl { link, args } => match &args.remote {
                Some(robot) => ctl_remote(&args, &link, robot),
                None => Ok(harvest_executive::ctl::run(&args, &domain).context("harvest ctl")?),
            },
            Command::Remote(args) => {
                harvest_remote_process::run(&args, &domain, process_name)
                    .with_context(|| stack_process_context("remote link", &domain))?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Fleet(args) => {
                harvest_remote_process::fleet::run(&args).context("fleet page")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Console {
                args,
                remote: Some(robot),
                link_file,
                connect,
            } => {
                let link = harvest_remote_process::link_session::LinkArgs {
                    link_file,
                    listen: Vec::new(),
                    connect,
                };
                station_console(&args, &robot, &link)?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Console { args, .. } => {
                harvest_console::run(&args, &domain, process_name).context("console")?;
                Ok(ExitCode::SUCCESS)
            }
            Command::Channels {
                schema: Some(topic),
            } => {
                let text = harvest_ipc::schema::schema_of_topic(&topic).with_context(|| {
                    format!("no channel {topic:?} in the catalogue (`harvest channels`)")
                })?;
                print!("{text}");
                Ok(ExitCode::SUCCESS)
            }
            Command::Channels { schema: None } => {
                for spec in harvest_ipc::catalogue::all_specs() {
                    println!(
                        "{:<24} {:<26} v{} {:?} buffer<= {:<3} writers<= {:<2} {}",
                        spec.topic,
                        spec.type_name,
                        spec.version,
                        spec.layer,
                        spec.qos.subscriber_max_buffer_size,
                        spec.qos.max_publishers,
                        spec.description
                    );
                }
                Ok(ExitCode::SUCCESS)
            }
        }
    }
}

/// The context of a failed stack process: its role, and when it was started by hand in a domain
/// where `harvest up` runs a stack, that stack's supervisor. Its processes already write the
/// channels this one would write, and single-writer channels (`harvest channels`: `writers<= 1`)
/// refuse a second publisher.
fn stack_process_context(role: &str, domain: &Domain) -> String {
    match harvest_supervisor::DomainLock::running_supervisor(domain) {
        Some(pid) if pid != nix::unistd::getppid().as_raw() => format!(
            "{role} (a stack is already running in domain {:?}: `harvest up` pid {pid}; its \
processes write this process's channels, and a channel with one writer accepts no second \
publisher)",
            domain.name()
        ),
        _ => role.to_owned(),
    }
}

fn clean(domain: &Domain, check: bool) -> Result<ExitCode> {
    if check {
        let files = harvest_ipc::cleanup::leftover_files(domain);
        for file in &files {
            println!("{}", file.display());
        }
        return Ok(if files.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::FAILURE
        });
    }
    let report = harvest_ipc::cleanup::remove_dead_nodes(domain)?;
    println!(
        "domain {domain}: removed {} dead node(s), {} alive, {} failed",
        report.removed_nodes.len(),
        report.alive_nodes,
        report.failed_nodes.len()
    );
    for (node, reason) in &report.failed_nodes {
        println!("  {node}: {reason}");
    }
    // With no node left, the domain's node registry in /dev/shm goes too.
    match harvest_ipc::cleanup::remove_unused_registry(domain)? {
        RegistryRemoval::Removed => println!("domain {domain}: node registry removed"),
        RegistryRemoval::Absent => {}
        RegistryRemoval::InUse { nodes } => {
            println!("domain {domain}: node registry kept ({nodes} node(s) of the domain exist)")
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `harvest console --remote ROBOT`: the robot's page on the station.
#[cfg(feature = "station")]
fn station_console(
    args: &harvest_console::ConsoleArgs,
    robot: &str,
    link: &harvest_remote_process::link_session::LinkArgs,
) -> Result<()> {
    let robot = harvest_remote::RobotName::parse(robot)?;
    harvest_station::run(args, robot, link).context("station console (harvest console --remote)")
}

#[cfg(not(feature = "station"))]
fn station_console(
    _args: &harvest_console::ConsoleArgs,
    _robot: &str,
    _link: &harvest_remote_process::link_session::LinkArgs,
) -> Result<()> {
    anyhow::bail!(
        "this build has no station console: build with the `station` feature (on by default)"
    )
}

/// `harvest ctl --remote ROBOT ...`: the same commands over the link.
fn ctl_remote(
    args: &harvest_executive::ctl::CtlArgs,
    link: &harvest_remote_process::link_session::LinkArgs,
    robot: &str,
) -> Result<ExitCode> {
    use harvest_executive::ctl::{CtlCommand, control_token};
    use harvest_remote_process::station_ctl::{self, Ask};
    let robot = harvest_remote::RobotName::parse(robot)?;
    let ask = match &args.command {
        CtlCommand::Status { json } => Ask::Status { json: *json },
        CtlCommand::Mark { .. } => {
            anyhow::bail!("`mark` is kept on the robot: run `harvest ctl mark` there")
        }
        other => Ask::Command(
            other
                .to_command()
                .context("a command that is not an operator command")?,
        ),
    };
    let token = match ask {
        Ask::Status { .. } => None,
        Ask::Command(command) => match control_token(args, robot.as_str()) {
            Ok(token) => Some(token),
            // A stop needs no authority: without a (valid) token it is sent without one.
            Err(error) if command == harvest_operator::Command::EmergencyStop => {
                eprintln!("estop: no control token ({error}); sent without it (a stop needs none)");
                None
            }
            Err(error) => return Err(error.into()),
        },
    };
    let timeout = std::time::Duration::from_millis(args.timeout_ms);
    station_ctl::run(robot, link, ask, token, timeout).context("harvest ctl --remote")
}

/// `harvest replay`: the replay's options, and `--check` with the perception arguments the
/// live process ran with.
#[derive(Debug, clap::Args)]
pub struct ReplayCommand {
    #[command(flatten)]
    replay: harvest_rec::ReplayArgs,
    /// Do not publish: re-run this build's perception on the recording's camera frames (recorded
    /// raw: `harvest recorder --camera raw`, or a clip) and compare its detections and scan
    /// requests with the recorded ones; exit 1 on any difference. Give perception the
    /// arguments it ran with (below).
    #[arg(long)]
    check: bool,
    /// With --check: floats within this absolute difference count as equal (default: exact).
    #[arg(long, requires = "check")]
    tolerance: Option<f64>,
    #[command(
        flatten,
        next_help_heading = "With --check: perception's arguments, as it ran"
    )]
    perception: harvest_perception_process::PerceptionArgs,
    #[command(
        flatten,
        next_help_heading = "With --check: the arms' and the vacuum supervisor's arguments, as they ran"
    )]
    control: ControlCheckArgs,
}

/// The control nodes' arguments for `harvest replay --check` (those of `harvest arm` and
/// `harvest vacuum` in the launch file). Whether a node ran without an operator is in its
/// tick records.
#[derive(Debug, clap::Args)]
struct ControlCheckArgs {
    /// `harvest arm --device`, both arms.
    #[arg(long, value_enum, default_value = "sim", requires = "check")]
    arm_device: harvest_arm_process::ArmDevice,
    /// `harvest arm --config` of arm 1.
    #[arg(long, requires = "check")]
    arm1_config: Option<std::path::PathBuf>,
    /// `harvest arm --config` of arm 2.
    #[arg(long, requires = "check")]
    arm2_config: Option<std::path::PathBuf>,
    /// `harvest vacuum --policy`.
    #[arg(long, value_enum, default_value = "2024", requires = "check")]
    vacuum_policy: harvest_vacuum_process::policy_arg::PolicyArg,
    /// `harvest vacuum --arms`.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2), requires = "check")]
    vacuum_arms: u8,
    /// `harvest vacuum --device` (its pressure thresholds and reach follow the device).
    #[arg(long, value_enum, default_value = "sim", requires = "check")]
    vacuum_device: harvest_vacuum_process::process::VacuumDevice,
    /// `harvest vacuum --config`.
    #[arg(long, requires = "check")]
    vacuum_config: Option<std::path::PathBuf>,
    /// `harvest monitor --on-violation` (the default launch file's `stop`); `print`: the live
    /// monitor published nothing, so its findings are not compared. Its thresholds are the
    /// monitor's defaults, as the launch files run it.
    #[arg(long, value_enum, default_value = "stop", requires = "check")]
    monitor_on_violation: harvest_monitor::violation_message::OnViolation,
}

impl ControlCheckArgs {
    /// The arms and the vacuum supervisor, built as these arguments say, on recorded devices.
    fn nodes(&self) -> Vec<Box<dyn harvest_rec::check::ControlRerun>> {
        use harvest_rec::check::{RecordedBoard, RecordedServos, arm_rerun, vacuum_rerun};
        let arm = |arm_id: harvest_ipc::ArmId, config: &Option<std::path::PathBuf>| {
            let id = arm_id.number();
            let args = harvest_arm_process::ArmArgs {
                id,
                device: self.arm_device,
                config: config.clone(),
                without_operator: false,
            };
            arm_rerun(
                arm_id,
                Box::new(move || {
                    harvest_arm_process::process::task::<RecordedServos>(&args)
                        .map_err(|error| format!("arm {id}: {error}"))
                }),
                harvest_arm_process::process::MAX_CONSECUTIVE_DEVICE_ERRORS,
            )
        };
        let vacuum_args = harvest_vacuum_process::process::VacuumArgs {
            policy: self.vacuum_policy,
            arms: self.vacuum_arms,
            device: self.vacuum_device,
            port: None,
            config: self.vacuum_config.clone(),
            without_operator: false,
        };
        vec![
            arm(harvest_ipc::ArmId::Arm1, &self.arm1_config),
            arm(harvest_ipc::ArmId::Arm2, &self.arm2_config),
            vacuum_rerun(
                Box::new(move || {
                    harvest_vacuum_process::process::task::<RecordedBoard>(&vacuum_args)
                        .map_err(|error| format!("vacuum: {error}"))
                }),
                harvest_vacuum_process::process::MAX_CONSECUTIVE_DEVICE_ERRORS,
            ),
        ]
    }
}

/// `harvest replay --check`: prints the report on stdout (the same for two runs on one file),
/// the speed on stderr; exit 1 when an output differs.
fn run_check(command: &ReplayCommand) -> anyhow::Result<ExitCode> {
    if command.replay.ros2 {
        anyhow::bail!("--check re-runs on harvest recordings, not ROS 2 bags (--ros2)");
    }
    let task = harvest_perception_process::build_task(&command.perception, None)
        .context("perception for --check")?;
    let controls = command.control.nodes();
    let rejudging = std::time::Instant::now();
    let monitor = match command.control.monitor_on_violation.action() {
        Some(action) => {
            let (mapping, checks) = harvest_monitor::MonitorArgs::default()
                .configs()
                .context("the monitor's settings")?;
            Some(
                harvest_monitor::recording::violation_messages(
                    &command.replay.files,
                    mapping,
                    checks,
                    action,
                )
                .context("re-judging the safety monitor's rules")?,
            )
        }
        None => None,
    };
    let monitor_wall_s = rejudging.elapsed().as_secs_f64();
    let report = harvest_rec::run_check(
        &command.replay.files,
        task,
        &controls,
        monitor.as_deref(),
        command.tolerance,
    )
    .context("replay --check")?;
    print!("{report}");
    // Every pass over the recording: the re-runs and the monitor's re-judging.
    let wall_s = report.rerun_wall_s() + monitor_wall_s;
    eprintln!(
        "re-ran {:.3} s of recording in {wall_s:.3} s ({:.2}x real time)",
        report.recorded_span_s(),
        report.recorded_span_s() / wall_s.max(1e-9)
    );
    if monitor.is_some() {
        eprintln!("  the safety monitor: re-judged in {monitor_wall_s:.3} s");
    }
    if let Some(first) = report.controls.first() {
        eprintln!(
            "  the control nodes: {:.3} s reading their records and inputs, then {} ({:.1}x real time in all)",
            report.controls_read_wall_s,
            report
                .controls
                .iter()
                .map(|control| format!(
                    "{} {} ticks in {:.3} s",
                    control.name, control.ticks_rerun, control.rerun_wall_s
                ))
                .collect::<Vec<_>>()
                .join(", "),
            first.recorded_span_ns as f64 * 1e-9 / report.controls_wall_s().max(1e-9)
        );
    }
    Ok(if report.differs() {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
