//! One harvesting episode, in process, on a simulated clock: the robot's nodes under the
//! robot's tick.
//!
//! The nodes are the ones the processes run, with the processes' own glue around them: the
//! executive ([`ExecutiveNode`], started harvesting as the simulated robot's launch profile
//! starts it), both arms ([`ArmTask`]) and the vacuum supervisor ([`VacuumTask`]), each under
//! [`harvest_node::Runner`] (the stop first, device faults, the operator's mode by the one
//! rule), on an in-process [`Schedule`] in the order executive, arm 1, arm 2, vacuum
//! supervisor, every 5 ms control period (200 Hz, [dual-arm sec. 2.2]). They exchange their
//! messages on the schedule's bus as over the channels: a node sees what the nodes before it
//! sent in the same period and the others' messages of the period before (arm 2 checks its
//! path against arm 1's fresh state; the arms see the supervisor's targets, grants and state
//! one period late). The devices are the simulated robot's, behind the hardware traits
//! ([`super::devices`]).
//!
//! Per period, in this order:
//! 1. a detection set captured from the world when due is published on `perception/apples`
//!    once the perception latency has passed ([`crate::harvest::detections`]); a requested
//!    emergency stop goes to the executive on `operator/command`, as the console sends it;
//! 2. the nodes tick;
//! 3. the run is observed: the nodes' events for the records and the safety monitor, the
//!    set-points the arms sent (`armN/command`), the stop as published
//!    (`safety/emergency_stop`), the end effectors as the simulator measures them;
//! 4. the simulated robot advances one period and the clock with it.
//!
//! The episode ends on the vacuum supervisor's `HarvestComplete` on `harvest/events`, decided
//! by the process's rule ([`harvest_vacuum::completion::CompletionWatch`], after
//! [`DEFAULT_COMPLETE_AFTER_MS`] with nothing left to do), as `harvest up --until-harvested`
//! ends.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use harvest_arm::node::{ArmNode, ArmNodeConfig, ServoOrder, pick_reachable};
use harvest_arm::task::{ArmDevices, ArmTask, DEFAULT_VALVE_REQUEST_RESEND_MS};
use harvest_executive_node::{ExecutiveDevices, ExecutiveNode, ExecutiveNodeConfig, messages};
use harvest_hw::platform::sim::SimPlatform;
use harvest_hw::tractor::sim::SimTractor;
use harvest_ipc::catalogue::{
    ARM_COMMAND, ARM_STATE, EMERGENCY_STOP, HARVEST_EVENTS, OPERATOR_COMMAND, OPERATOR_MODE,
    PERCEPTION_APPLES,
};
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase as PhaseCode, ArmState, HarvestEventKind, HarvestEventSource,
    OperatorModeCode, OperatorModeState,
};
use harvest_ipc::{Clock, ManualClock};
use harvest_node::in_process::NodeHandle;
use harvest_node::{Node, Runner, RunnerConfig, Schedule};
use harvest_operator::{Command, ControlToken, ExecutiveConfig};
use harvest_robot_model::ModeSource;
use harvest_safety::safety_monitor::Violation;
use harvest_sim::physics::ArmId;
use harvest_sim::robot::SimRobot;
use harvest_sim::scenario::Scenario;
use harvest_vacuum::completion::DEFAULT_COMPLETE_AFTER_MS;
use harvest_vacuum::node::{VacuumNode, VacuumNodeConfig, VacuumNodeEvent};
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::PressureConfig;
use harvest_vacuum::replan::PlannerConfig;
use harvest_vacuum::task::{BoardDevices, VacuumTask};
use rand::SeedableRng;
use rand::rngs::SmallRng;

use super::detections::{DetectionModel, detect};
use super::devices::{InProcessServos, InProcessValveBoard, SharedRobot};
use super::error::HarvestEvalError;
use super::records::{AppleRecord, Recorder};
use super::safety::SafetyTrace;

/// The control period, ns (200 Hz).
pub const CONTROL_PERIOD_NS: u64 = 5_000_000;
/// Stack-clock time of the episode start, ns (any non-zero origin).
const EPOCH_NS: u64 = 1_000_000_000;
/// Decorrelates the detection noise from the world's own random streams.
const DETECTION_STREAM: u64 = 0x5eed_de7e_c710_0001;
/// Joint rate below which an arm counts as stopped, m/s or rad/s.
const STOPPED_RATE: f64 = 1e-3;

/// An arm as its process runs it, on the simulated robot's servos.
type Arm = ArmTask<InProcessServos>;
/// The vacuum supervisor as its process runs it, on the simulated robot's valve board.
type Vacuum = VacuumTask<InProcessValveBoard>;
/// The executive without a platform or a tractor: the episode harvests where the robot stands
/// (the types name the drivers a launch file would choose; none is opened).
type Executive = ExecutiveNode<SimPlatform, SimTractor>;

/// Where an episode's detection sets come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectionFeed {
    /// Captured by the runner from the ground truth through [`DetectionModel`].
    Model,
    /// Handed in by the owner of the episode ([`Episode::deliver`]), e.g. perception on
    /// rendered frames (`harvest eval row`).
    External,
}

/// Where the operator's mode comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeFeed {
    /// The executive's node, started harvesting (the simulated robot's launch profile).
    Executive,
    /// Published by the owner of the episode ([`Episode::publish_mode`]), e.g. the row's stop
    /// cycle (`harvest eval row`); the e-stop is then published directly.
    External,
}

/// What to run.
#[derive(Debug, Clone)]
pub struct EpisodeConfig {
    /// The world (with the timing profile applied).
    pub scenario: Scenario,
    /// Coordination policy.
    pub policy: PolicyKind,
    /// 1: arm 1 alone harvests; 2: both.
    pub arms: u8,
    /// World seed.
    pub seed: u64,
    /// Simulated time limit, s.
    pub max_episode_s: f64,
    /// Detection sets (used with [`DetectionFeed::Model`]).
    pub detection: DetectionModel,
    /// Where the detection sets come from.
    pub detection_feed: DetectionFeed,
    /// Where the operator's mode comes from.
    pub mode_feed: ModeFeed,
    /// Keep the full event log.
    pub keep_events: bool,
    /// Feed the safety monitor.
    pub check_safety: bool,
    /// Engage the emergency stop at this simulated time (and keep it engaged), s.
    pub emergency_stop_at_s: Option<f64>,
    /// Arm node settings.
    pub arm_node: ArmNodeConfig,
    /// The vacuum supervisor's attachment inference.
    pub pressure: PressureConfig,
    /// The vacuum supervisor's assignment (Algorithm 1 and re-planning).
    pub planner: PlannerConfig,
}

impl EpisodeConfig {
    /// An episode of `scenario` with default settings.
    pub fn new(scenario: Scenario, policy: PolicyKind, arms: u8, seed: u64) -> Self {
        Self {
            scenario,
            policy,
            arms,
            seed,
            max_episode_s: 900.0,
            detection: DetectionModel::default(),
            detection_feed: DetectionFeed::Model,
            mode_feed: ModeFeed::Executive,
            keep_events: true,
            check_safety: true,
            emergency_stop_at_s: None,
            arm_node: ArmNodeConfig::default(),
            pressure: PressureConfig::default(),
            planner: PlannerConfig::default(),
        }
    }
}

/// Simulated reaction to an emergency stop.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct EmergencyStopReaction {
    /// When the stop was requested, s.
    pub requested_s: f64,
    /// From the request until the arms' and the vacuum supervisor's runners applied the stop
    /// (every valve commanded closed, both arms' drives told to brake), s.
    pub commanded_s: Option<f64>,
    /// From the request until every gate reported closed at its end stop, s.
    pub valves_closed_s: Option<f64>,
    /// From the request until both arms published the `Stopped` phase on their state channel
    /// (their drives braked: what a live observer of `arm{1,2}/state` sees), s.
    pub arms_holding_s: Option<f64>,
    /// From the request until every joint of both arms moved slower than 1 mm/s or 1 mrad/s, s.
    pub arms_stopped_s: Option<f64>,
    /// Phases of the arms when the stop was requested.
    pub phases_at_request: [String; 2],
}

/// What one episode produced.
#[derive(Debug, Clone)]
pub struct EpisodeOutcome {
    /// World seed.
    pub seed: u64,
    /// Arms that harvested (1: arm 1 alone, 2: both).
    pub arms: u8,
    /// Apples in the world.
    pub apples_in_world: u32,
    /// Event log and attempts.
    pub recorder: Recorder,
    /// Per true apple that was attempted.
    pub apples: Vec<AppleRecord>,
    /// Time from the start to the end of the last attempt, s.
    pub duration_s: f64,
    /// Simulated time when the episode stopped, s.
    pub end_s: f64,
    /// True when the time limit cut the episode short.
    pub truncated: bool,
    /// Safety violations (empty without `check_safety`).
    pub violations: Vec<Violation>,
    /// Trace events the monitor judged.
    pub trace_events: u64,
    /// The emergency-stop measurement, if one was requested.
    pub emergency_stop: Option<EmergencyStopReaction>,
}

fn vacuum_arm(arm: usize) -> ArmId {
    ArmId::ALL[arm]
}

/// The nodes of the schedule.
#[derive(Debug, Clone, Copy)]
struct Nodes {
    arms: [NodeHandle; 2],
    vacuum: NodeHandle,
}

/// The episode's own read positions on the bus.
#[derive(Debug, Default)]
struct Cursors {
    events: u64,
    commands: [u64; 2],
    emergency_stop: u64,
}

/// Everything one episode steps. [`run_episode`] runs one to its end; an owner that moves the
/// world or feeds the detections itself (`harvest eval row`) steps it with [`Episode::tick`].
pub struct Episode {
    config: EpisodeConfig,
    clock: ManualClock,
    robot: SharedRobot,
    schedule: Schedule,
    nodes: Nodes,
    rng: SmallRng,
    pending_sets: VecDeque<(u64, Box<AppleDetections>)>,
    next_capture_ns: u64,
    set_seq: u64,
    arm_states: [Option<ArmState>; 2],
    cursors: Cursors,
    recorder: Recorder,
    safety: Option<SafetyTrace>,
    /// The vacuum supervisor's `HarvestComplete` heard at the last tick, and ever.
    completed_last_tick: bool,
    completed: bool,
    estop: Option<EmergencyStopReaction>,
}

/// Runs one episode.
pub fn run_episode(config: &EpisodeConfig) -> Result<EpisodeOutcome, HarvestEvalError> {
    if !(config.max_episode_s.is_finite() && config.max_episode_s > 0.0) {
        return Err(HarvestEvalError::InvalidArgument {
            arg: "max_episode_s",
            value: config.max_episode_s.to_string(),
            reason: "must be finite and > 0",
        });
    }
    let mut episode = Episode::new(config.clone())?;
    let max_ns = EPOCH_NS + (config.max_episode_s * 1e9) as u64;
    let mut truncated = false;
    loop {
        let now_ns = episode.clock.now_ns();
        if now_ns >= max_ns {
            truncated = true;
            break;
        }
        episode.tick(now_ns)?;
        if episode.finished() {
            break;
        }
    }
    Ok(episode.finish(truncated))
}

/// The runner of `handle` in `schedule`.
fn runner<N: Node + 'static>(
    schedule: &Schedule,
    handle: NodeHandle,
) -> Result<&Runner<N>, HarvestEvalError> {
    schedule.runner::<N>(handle).ok_or_else(|| {
        HarvestEvalError::Node(format!("no {} in the schedule", std::any::type_name::<N>()))
    })
}

/// The executive of an episode (module documentation).
fn executive() -> Result<(Executive, ExecutiveDevices<SimPlatform, SimTractor>), HarvestEvalError> {
    let devices = ExecutiveDevices::new(None, None, None);
    let token =
        ControlToken::generate().map_err(|error| HarvestEvalError::Executive(error.to_string()))?;
    let config = ExecutiveNodeConfig {
        executive: ExecutiveConfig {
            initial_mode: OperatorModeCode::Harvesting,
            ..ExecutiveConfig::default()
        },
        token,
        previous: None,
        row: None,
        travel_max_m: [0.0; 2],
    };
    let node = Executive::new(config, &devices)
        .map_err(|error| HarvestEvalError::Executive(error.to_string()))?;
    Ok((node, devices))
}

impl Episode {
    /// An episode in the world of `config.scenario` generated from `config.seed`.
    pub fn new(config: EpisodeConfig) -> Result<Self, HarvestEvalError> {
        let robot = SimRobot::new(&config.scenario, config.seed)?;
        Self::with_robot(config, robot)
    }

    /// An episode on `robot` (e.g. in a row's world); `config.scenario` is not used for the
    /// world.
    pub fn with_robot(config: EpisodeConfig, robot: SimRobot) -> Result<Self, HarvestEvalError> {
        let clock = ManualClock::starting_at(EPOCH_NS);
        let robot = Rc::new(RefCell::new(robot));
        // The processes' settings, but for the device reads: the in-process robot fails none
        // unless the evaluation has a bug, which ends the episode at once.
        let runner_config = RunnerConfig {
            max_read_failures: 1,
            mode_source: ModeSource::Executive,
        };
        let mut schedule = Schedule::new(EPOCH_NS);
        if config.mode_feed == ModeFeed::Executive {
            let (node, devices) = executive()?;
            schedule.add(
                Runner::new(node, devices, runner_config),
                CONTROL_PERIOD_NS,
                EPOCH_NS,
            );
        }
        let mut arms = Vec::with_capacity(2);
        for arm in ArmId::ALL {
            let task = Arm::new(
                ArmNode::new(arm, config.arm_node)?,
                DEFAULT_VALVE_REQUEST_RESEND_MS,
            );
            let servos = ArmDevices(InProcessServos::new(robot.clone(), arm, clock.clone()));
            arms.push(schedule.add(
                Runner::new(task, servos, runner_config),
                CONTROL_PERIOD_NS,
                EPOCH_NS,
            ));
        }
        let arm_node = config.arm_node;
        let enabled = [true, config.arms >= 2];
        let vacuum = VacuumNode::new(
            VacuumNodeConfig {
                policy: config.policy,
                pressure: config.pressure,
                planner: config.planner,
                arms_enabled: enabled,
                ..VacuumNodeConfig::default()
            },
            Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
                pick_reachable(arm, *centre, radius_m, &arm_node)
            }),
        )?;
        let board = BoardDevices::new(InProcessValveBoard::new(robot.clone(), clock.clone()));
        let vacuum = schedule.add(
            Runner::new(
                Vacuum::new(vacuum, enabled, DEFAULT_COMPLETE_AFTER_MS),
                board,
                runner_config,
            ),
            CONTROL_PERIOD_NS,
            EPOCH_NS,
        );
        let nodes = Nodes {
            arms: [arms[0], arms[1]],
            vacuum,
        };
        let rng = SmallRng::seed_from_u64(config.seed ^ DETECTION_STREAM);
        Ok(Self {
            recorder: Recorder::new(config.keep_events),
            safety: config.check_safety.then(SafetyTrace::default),
            config,
            clock,
            robot,
            schedule,
            nodes,
            rng,
            pending_sets: VecDeque::new(),
            next_capture_ns: EPOCH_NS,
            set_seq: 0,
            arm_states: [None; 2],
            cursors: Cursors::default(),
            completed_last_tick: false,
            completed: false,
            estop: None,
        })
    }

    /// Simulated time since the episode started, s, of the stack-clock stamp `now_ns`.
    pub fn t_s(now_ns: u64) -> f64 {
        now_ns.saturating_sub(EPOCH_NS) as f64 * 1e-9
    }

    /// The stack clock now, ns (advances one control period per [`Episode::tick`]).
    pub fn now_ns(&self) -> u64 {
        self.clock.now_ns()
    }

    /// The simulated robot (and its world).
    pub fn robot(&self) -> &SharedRobot {
        &self.robot
    }

    /// The arms' latest published states.
    pub fn arm_states(&self) -> &[Option<ArmState>; 2] {
        &self.arm_states
    }

    /// The event log and the attempts so far.
    pub fn recorder(&self) -> &Recorder {
        &self.recorder
    }

    /// Hands in a detection set published on `perception/apples` at `deliver_ns` (sets are
    /// delivered in the order handed in).
    pub fn deliver(&mut self, deliver_ns: u64, set: Box<AppleDetections>) {
        self.pending_sets.push_back((deliver_ns, set));
    }

    /// Publishes the operator's mode (with [`ModeFeed::External`]); the arms and the vacuum
    /// supervisor obey it at their next tick by the one rule
    /// ([`harvest_robot_model::obedience`](mod@harvest_robot_model::obedience)).
    pub fn publish_mode(&mut self, mut mode: OperatorModeState) {
        let now_ns = self.clock.now_ns();
        mode.header.capture_ns = now_ns;
        self.schedule.bus_mut().publish(OPERATOR_MODE, mode, now_ns);
    }

    /// The vacuum supervisor reported the harvest complete at the last tick.
    pub fn completed_last_tick(&self) -> bool {
        self.completed_last_tick
    }

    /// One control period at `now_ns` (= [`Episode::now_ns`]); advances the robot and the
    /// clock.
    pub fn tick(&mut self, now_ns: u64) -> Result<(), HarvestEvalError> {
        let t_s = Self::t_s(now_ns);
        // 1. What the operator and perception send.
        if let Some(at) = self.config.emergency_stop_at_s
            && t_s >= at
            && self.estop.is_none()
        {
            self.request_emergency_stop(now_ns, at);
        }
        if self.config.detection_feed == DetectionFeed::Model && now_ns >= self.next_capture_ns {
            self.set_seq += 1;
            let set = {
                let robot = self.robot.borrow();
                detect(
                    robot.world(),
                    now_ns,
                    self.set_seq,
                    &self.config.detection,
                    &mut self.rng,
                )
            };
            let deliver_ns = now_ns + (self.config.detection.latency_s * 1e9) as u64;
            self.pending_sets.push_back((deliver_ns, Box::new(set)));
            self.next_capture_ns += (self.config.detection.period_s * 1e9) as u64;
        }
        if let Some((at, _)) = self.pending_sets.front()
            && *at <= now_ns
            && let Some((_, set)) = self.pending_sets.pop_front()
        {
            self.schedule
                .bus_mut()
                .publish(PERCEPTION_APPLES, *set, now_ns);
        }

        // 2. The nodes.
        self.schedule
            .run_until(now_ns)
            .map_err(|error| HarvestEvalError::Node(error.message))?;

        // 3. What they did.
        self.observe(now_ns, t_s)?;

        // 4. Advance the world and the clock.
        let period_s = CONTROL_PERIOD_NS as f64 * 1e-9;
        let events = self.robot.borrow_mut().step(period_s)?;
        for event in &events {
            self.recorder.on_world_event(t_s + period_s, event);
        }
        self.clock.advance_ns(CONTROL_PERIOD_NS);
        Ok(())
    }

    /// Sends the operator's e-stop: to the executive as the console does (it needs no token),
    /// or, without an executive, as the executive would publish it.
    fn request_emergency_stop(&mut self, now_ns: u64, at_s: f64) {
        let bus = self.schedule.bus_mut();
        match self.config.mode_feed {
            ModeFeed::Executive => {
                let mut command = Command::EmergencyStop.to_message(1, 1, "", "harvest eval");
                command.header.capture_ns = now_ns;
                bus.publish(OPERATOR_COMMAND, command, now_ns);
            }
            ModeFeed::External => {
                let stop = messages::emergency_stop(now_ns, true, "harvest eval");
                bus.publish(EMERGENCY_STOP, stop, now_ns);
            }
        }
        self.estop = Some(EmergencyStopReaction {
            requested_s: at_s,
            commanded_s: None,
            valves_closed_s: None,
            arms_holding_s: None,
            arms_stopped_s: None,
            phases_at_request: self
                .arm_states
                .map(|s| s.map_or_else(|| "unknown".to_owned(), |s| format!("{:?}", s.phase))),
        });
    }

    /// Step 3 of the module documentation, in the order the nodes ticked.
    fn observe(&mut self, now_ns: u64, t_s: f64) -> Result<(), HarvestEvalError> {
        let bus = self.schedule.bus_mut();
        let mut stops = Vec::new();
        bus.read_since(EMERGENCY_STOP, &mut self.cursors.emergency_stop, |stop| {
            stops.push(stop.engaged != 0)
        });
        let mut completed = false;
        bus.read_since(HARVEST_EVENTS, &mut self.cursors.events, |event| {
            completed |= event.source == HarvestEventSource::Vacuum
                && event.kind == HarvestEventKind::HarvestComplete;
        });
        let mut set_points: [Vec<ServoOrder>; 2] = Default::default();
        for (i, orders) in set_points.iter_mut().enumerate() {
            bus.read_since(ARM_COMMAND[i], &mut self.cursors.commands[i], |command| {
                if command.hold == 0 {
                    orders.push(ServoOrder::Track {
                        position: command.joint_position,
                        velocity: command.joint_velocity,
                    });
                }
            });
            self.arm_states[i] = bus.latest(ARM_STATE[i]);
        }
        self.completed_last_tick = completed;
        self.completed |= completed;
        if let Some(safety) = self.safety.as_mut() {
            for engaged in stops {
                safety.emergency_stop(now_ns, engaged)?;
            }
        }

        for i in 0..2 {
            let runner = runner::<Arm>(&self.schedule, self.nodes.arms[i])?;
            let Some(out) = runner.node().last_output() else {
                continue;
            };
            for event in &out.events {
                self.recorder.on_arm_event(t_s, i, event);
            }
            if let Some(safety) = self.safety.as_mut() {
                safety.arm_events(now_ns, vacuum_arm(i), &out.events)?;
            }
        }
        let out = runner::<Vacuum>(&self.schedule, self.nodes.vacuum)?
            .node()
            .node()
            .last_output();
        for event in &out.events {
            if let VacuumNodeEvent::TargetDispatched { arm, target } = event {
                let robot = self.robot.borrow();
                self.recorder
                    .on_dispatch(t_s, arm.index(), target, robot.world());
            }
            self.recorder.on_vacuum_event(t_s, event);
        }
        if let Some(safety) = self.safety.as_mut() {
            safety.vacuum_events(now_ns, &out.events)?;
            for (i, orders) in set_points.iter().enumerate() {
                for order in orders {
                    safety.servo_order(now_ns, vacuum_arm(i), order)?;
                }
            }
            let robot = self.robot.borrow();
            safety.end_effectors(
                now_ns,
                [
                    robot.end_effector_in_robot_m(ArmId::Arm1),
                    robot.end_effector_in_robot_m(ArmId::Arm2),
                ],
            )?;
        }
        self.measure_estop(t_s)
    }

    fn measure_estop(&mut self, t_s: f64) -> Result<(), HarvestEvalError> {
        if self.estop.is_none() {
            return Ok(());
        }
        let applied = runner::<Arm>(&self.schedule, self.nodes.arms[0])?.emergency_stop()
            && runner::<Arm>(&self.schedule, self.nodes.arms[1])?.emergency_stop()
            && runner::<Vacuum>(&self.schedule, self.nodes.vacuum)?.emergency_stop();
        let robot = self.robot.borrow();
        let (open, in_transit, _) = robot.valve_readings();
        let valves_closed = open.iter().chain(&in_transit).all(|v| !v);
        let still = ArmId::ALL
            .iter()
            .all(|&arm| robot.encoders(arm).1.iter().all(|v| v.abs() < STOPPED_RATE));
        let holding = self
            .arm_states
            .iter()
            .all(|s| s.is_some_and(|s| s.phase == PhaseCode::Stopped));
        let Some(m) = self.estop.as_mut() else {
            return Ok(());
        };
        let since = t_s - m.requested_s;
        for (slot, reached) in [
            (&mut m.commanded_s, applied),
            (&mut m.valves_closed_s, valves_closed),
            (&mut m.arms_holding_s, holding),
            (&mut m.arms_stopped_s, still),
        ] {
            if slot.is_none() && reached {
                *slot = Some(since);
            }
        }
        Ok(())
    }

    /// The episode is over: the vacuum supervisor reported the harvest complete (or, with an
    /// emergency stop, its reaction is measured).
    pub fn finished(&self) -> bool {
        if let Some(m) = &self.estop {
            return m.commanded_s.is_some()
                && m.valves_closed_s.is_some()
                && m.arms_holding_s.is_some()
                && m.arms_stopped_s.is_some();
        }
        self.completed
    }

    /// Ends the episode: the nodes' devices in their safe state, the attempts classified and
    /// the outcome collected.
    pub fn finish(mut self, truncated: bool) -> EpisodeOutcome {
        let end_ns = self.clock.now_ns();
        self.schedule.shutdown();
        self.recorder.finalize();
        let robot = self.robot.borrow();
        let apples = self.recorder.apples(robot.world());
        let (violations, trace_events) = match self.safety.take() {
            Some(safety) => {
                let count = safety.event_count();
                (safety.finish(end_ns), count)
            }
            None => (Vec::new(), 0),
        };
        let duration_s = self
            .recorder
            .attempts
            .iter()
            .filter_map(|a| a.ended_s)
            .fold(0.0, f64::max);
        EpisodeOutcome {
            seed: self.config.seed,
            arms: self.config.arms,
            apples_in_world: robot.world().apples().len() as u32,
            apples,
            duration_s,
            end_s: Self::t_s(end_ns),
            truncated,
            violations,
            trace_events,
            emergency_stop: self.estop.take(),
            recorder: std::mem::take(&mut self.recorder),
        }
    }
}
