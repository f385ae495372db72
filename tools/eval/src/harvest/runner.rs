//! One harvesting episode, in process, on a simulated clock.
//!
//! Per 5 ms control period (200 Hz, [dual-arm sec. 2.2]), in this order:
//! 1. a detection set is captured from the world when due and delivered after the perception
//!    latency ([`crate::harvest::detections`]);
//! 2. the devices are read through their traits: both arms' encoders (`ArmServos::feedback`),
//!    the valve states and pressures (`ValveBoard`);
//! 3. arm 1's node steps, then arm 2's with arm 1's fresh state (the arm crate's wiring note:
//!    the arm that moves second checks its path against the first one's), each seeing the vacuum
//!    supervisor's state, answers and targets of the previous period (one period of transport
//!    latency, as over the channels);
//! 4. the vacuum node steps with both arms' states and valve requests, the board readings and
//!    the delivered detection set;
//! 5. the outputs go to the devices through the same traits (`set_valve` / `close_all`,
//!    `command` / `hold`), and to the safety monitor as trace events;
//! 6. the simulated robot advances one period and the clock with it.
//!
//! The episode ends when nothing is left to do: the vacuum node has nothing assigned, dispatched
//! or running, both arms are idle, and a detection set has been processed since the last attempt
//! ended (so a failed apple still on the tree is retried).

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

use harvest_arm::node::{
    ArmNode, ArmNodeConfig, ArmNodeInput, EncoderSample, OtherArmInput, ServoOrder, pick_reachable,
};
use harvest_hw::arm_servos::ArmServos;
use harvest_hw::valve_board::{ValveBoard, ValveId, ValveState};
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase as PhaseCode, ArmState, ArmTarget, VacuumState, ValveGrant,
};
use harvest_ipc::{Clock, ManualClock};
use harvest_safety::safety_monitor::Violation;
use harvest_sim::physics::ArmId;
use harvest_sim::robot::SimRobot;
use harvest_sim::scenario::Scenario;
use harvest_vacuum::node::{
    BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeEvent, VacuumNodeInput,
};
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::PressureConfig;
use harvest_vacuum::replan::PlannerConfig;
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

/// Where an episode's detection sets come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectionFeed {
    /// Captured by the runner from the ground truth through [`DetectionModel`].
    Model,
    /// Handed in by the owner of the episode ([`Episode::deliver`]), e.g. perception on
    /// rendered frames (`harvest eval row`).
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
    /// From the request until every valve was commanded closed and both arms' drives were told
    /// to brake, s.
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

fn device_error(
    device: &'static str,
    stamp_ns: u64,
    error: impl std::fmt::Display,
) -> HarvestEvalError {
    HarvestEvalError::Device {
        device,
        stamp_ns,
        message: error.to_string(),
    }
}

/// Everything one episode steps. [`run_episode`] runs one to its end; an owner that moves the
/// world or feeds the detections itself (`harvest eval row`) steps it with [`Episode::tick`].
pub struct Episode {
    config: EpisodeConfig,
    clock: ManualClock,
    robot: SharedRobot,
    servos: [InProcessServos; 2],
    board: InProcessValveBoard,
    arms: [ArmNode; 2],
    vacuum: VacuumNode,
    rng: SmallRng,
    pending_sets: VecDeque<(u64, Box<AppleDetections>)>,
    next_capture_ns: u64,
    set_seq: u64,
    targets: [Option<ArmTarget>; 2],
    grants: [Option<ValveGrant>; 2],
    vacuum_state: Option<VacuumState>,
    arm_states: [Option<ArmState>; 2],
    applied_valves: [bool; 4],
    recorder: Recorder,
    safety: Option<SafetyTrace>,
    last_replan_ns: u64,
    last_attempt_end_ns: u64,
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
        let servos = [
            InProcessServos::new(robot.clone(), ArmId::Arm1, clock.clone()),
            InProcessServos::new(robot.clone(), ArmId::Arm2, clock.clone()),
        ];
        let board = InProcessValveBoard::new(robot.clone(), clock.clone());
        let arms = [
            ArmNode::new(ArmId::Arm1, config.arm_node)?,
            ArmNode::new(ArmId::Arm2, config.arm_node)?,
        ];
        let arm_node = config.arm_node;
        let vacuum = VacuumNode::new(
            VacuumNodeConfig {
                policy: config.policy,
                pressure: config.pressure,
                planner: config.planner,
                arms_enabled: [true, config.arms >= 2],
                ..VacuumNodeConfig::default()
            },
            Box::new(move |arm: ArmId, centre: &[f64; 3], radius_m: f64| {
                pick_reachable(arm, *centre, radius_m, &arm_node)
            }),
        )?;
        let rng = SmallRng::seed_from_u64(config.seed ^ DETECTION_STREAM);
        let mut episode = Self {
            recorder: Recorder::new(config.keep_events),
            safety: config.check_safety.then(SafetyTrace::default),
            config,
            clock,
            robot,
            servos,
            board,
            arms,
            vacuum,
            rng,
            pending_sets: VecDeque::new(),
            next_capture_ns: EPOCH_NS,
            set_seq: 0,
            targets: [None; 2],
            grants: [None; 2],
            vacuum_state: None,
            arm_states: [None; 2],
            applied_valves: [false, true, false, true],
            last_replan_ns: 0,
            last_attempt_end_ns: 0,
            estop: None,
        };
        // No executive runs here: said explicitly, as the launch files without one do (a row
        // episode obeys the stop cycle's mode instead, [`Episode::obey`]).
        episode.obey(harvest_robot_model::obedience(
            None,
            harvest_robot_model::ModeSource::WithoutOperator,
            EPOCH_NS,
        ));
        Ok(episode)
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

    /// Hands in a detection set delivered to the vacuum supervisor at `deliver_ns` (sets are
    /// delivered in the order handed in).
    pub fn deliver(&mut self, deliver_ns: u64, set: Box<AppleDetections>) {
        self.pending_sets.push_back((deliver_ns, set));
    }

    /// Applies what the operator's mode allows
    /// ([`harvest_robot_model::obedience`](mod@harvest_robot_model::obedience)) as the processes
    /// do: the vacuum supervisor dispatches no new target to a held arm, and a held arm takes up
    /// none.
    pub fn obey(&mut self, rule: harvest_robot_model::Obedience) {
        self.vacuum.hold_dispatch(rule.targets_held);
        for (arm, held) in self.arms.iter_mut().zip(rule.targets_held) {
            arm.hold_targets(held);
        }
    }

    /// One control period at `now_ns` (= [`Episode::now_ns`]); advances the robot and the
    /// clock.
    pub fn tick(&mut self, now_ns: u64) -> Result<(), HarvestEvalError> {
        let t_s = Self::t_s(now_ns);
        let estop_at = self.config.emergency_stop_at_s;
        let estop = estop_at.is_some_and(|at| t_s >= at);
        if let Some(at) = estop_at
            && estop
            && self.estop.is_none()
        {
            if let Some(safety) = self.safety.as_mut() {
                safety.emergency_stop(now_ns, true)?;
            }
            self.estop = Some(EmergencyStopReaction {
                requested_s: at,
                commanded_s: None,
                valves_closed_s: None,
                arms_holding_s: None,
                arms_stopped_s: None,
                phases_at_request: self
                    .arm_states
                    .map(|s| s.map_or_else(|| "unknown".to_owned(), |s| format!("{:?}", s.phase))),
            });
        }

        // 1. Detections.
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
        let delivered = match self.pending_sets.front() {
            Some((at, _)) if *at <= now_ns => self.pending_sets.pop_front().map(|(_, s)| s),
            _ => None,
        };

        // 2. Devices.
        let mut feedback = [None; 2];
        for (i, servos) in self.servos.iter_mut().enumerate() {
            feedback[i] = servos
                .feedback()
                .map_err(|e| device_error("arm servos", now_ns, e))?
                .map(|f| EncoderSample {
                    capture_ns: f.capture_ns,
                    position: f.position,
                    velocity: f.velocity,
                });
        }
        let states = self
            .board
            .valve_states()
            .map_err(|e| device_error("valve board", now_ns, e))?;
        let pressures = self
            .board
            .pressures()
            .map_err(|e| device_error("valve board", now_ns, e))?;
        let readings = BoardReadings {
            stamp_ns: now_ns,
            valve_open: states
                .0
                .map(|s| matches!(s, ValveState::Open | ValveState::Opening)),
            valve_in_transit: states.0.map(ValveState::is_in_transit),
            pressure_mmh2o: pressures.to_array(),
        };

        // 3. Arm nodes: arm 1, then arm 2 with arm 1's fresh state.
        let mut orders = [ServoOrder::Hold; 2];
        let mut requests = [None; 2];
        for i in 0..2 {
            let other = 1 - i;
            let input = ArmNodeInput {
                now_ns,
                feedback: feedback[i],
                target: self.targets[i].as_ref(),
                vacuum: self.vacuum_state.as_ref(),
                grant: self.grants[i].as_ref(),
                other_arm: self.arm_states[other].as_ref().map(|state| OtherArmInput {
                    state,
                    target: self.targets[other].as_ref(),
                }),
                emergency_stop: estop,
            };
            let out = self.arms[i].step(&input);
            orders[i] = out.servo;
            requests[i] = Some(out.valve_request);
            self.arm_states[i] = Some(out.state);
            for event in &out.events {
                self.recorder.on_arm_event(t_s, i, event);
            }
            if let Some(safety) = self.safety.as_mut() {
                safety.arm_events(now_ns, vacuum_arm(i), &out.events)?;
            }
        }

        // 4. Vacuum node.
        let input = VacuumNodeInput {
            now_ns,
            arm_states: [self.arm_states[0].as_ref(), self.arm_states[1].as_ref()],
            valve_requests: [requests[0].as_ref(), requests[1].as_ref()],
            readings: Some(readings),
            detections: delivered.as_deref(),
            emergency_stop: estop,
        };
        let out = self.vacuum.step(&input);
        for event in &out.events {
            match event {
                VacuumNodeEvent::TargetDispatched { arm, target } => {
                    let robot = self.robot.borrow();
                    self.recorder
                        .on_dispatch(t_s, arm.index(), target, robot.world());
                }
                VacuumNodeEvent::Replanned { .. } => self.last_replan_ns = now_ns,
                VacuumNodeEvent::AttemptFinished { .. }
                | VacuumNodeEvent::DispatchTimedOut { .. }
                | VacuumNodeEvent::TargetRefused { .. } => self.last_attempt_end_ns = now_ns,
                _ => {}
            }
            self.recorder.on_vacuum_event(t_s, event);
        }
        if let Some(safety) = self.safety.as_mut() {
            safety.vacuum_events(now_ns, &out.events)?;
        }
        for i in 0..2 {
            if let Some(target) = out.targets[i] {
                self.targets[i] = Some(target);
            }
            if let Some(grant) = out.grants[i] {
                self.grants[i] = Some(grant);
            }
        }
        self.vacuum_state = Some(out.state);
        let (close_all, commands) = (out.close_all, out.valve_commands);

        // 5. Outputs to the devices.
        if close_all {
            self.board
                .close_all()
                .map_err(|e| device_error("valve board", now_ns, e))?;
            self.applied_valves = [false; 4];
        }
        for (i, &open) in commands.iter().enumerate() {
            if open != self.applied_valves[i] {
                self.board
                    .set_valve(ValveId(i as u8 + 1), open)
                    .map_err(|e| device_error("valve board", now_ns, e))?;
                self.applied_valves[i] = open;
            }
        }
        for (i, order) in orders.iter().enumerate() {
            match *order {
                ServoOrder::Track { position, velocity } => self.servos[i]
                    .command(position, velocity)
                    .map_err(|e| device_error("arm servos", now_ns, e))?,
                ServoOrder::Hold => self.servos[i]
                    .hold()
                    .map_err(|e| device_error("arm servos", now_ns, e))?,
            }
            if let Some(safety) = self.safety.as_mut() {
                safety.servo_order(now_ns, vacuum_arm(i), order)?;
            }
        }
        if let Some(safety) = self.safety.as_mut() {
            let robot = self.robot.borrow();
            safety.end_effectors(
                now_ns,
                [
                    robot.end_effector_in_robot_m(ArmId::Arm1),
                    robot.end_effector_in_robot_m(ArmId::Arm2),
                ],
            )?;
        }
        self.measure_estop(t_s, &orders, &states.0);

        // 6. Advance the world and the clock.
        let period_s = CONTROL_PERIOD_NS as f64 * 1e-9;
        let events = self.robot.borrow_mut().step(period_s)?;
        for event in &events {
            self.recorder.on_world_event(t_s + period_s, event);
        }
        self.clock.advance_ns(CONTROL_PERIOD_NS);
        Ok(())
    }

    fn measure_estop(&mut self, t_s: f64, orders: &[ServoOrder; 2], valves: &[ValveState; 4]) {
        let Some(m) = self.estop.as_mut() else {
            return;
        };
        if m.commanded_s.is_none()
            && self.applied_valves == [false; 4]
            && orders.iter().all(|o| *o == ServoOrder::Hold)
        {
            m.commanded_s = Some(t_s - m.requested_s);
        }
        if m.valves_closed_s.is_none() && valves.iter().all(|s| *s == ValveState::Closed) {
            m.valves_closed_s = Some(t_s - m.requested_s);
        }
        if m.arms_holding_s.is_none()
            && self
                .arm_states
                .iter()
                .all(|s| s.is_some_and(|s| s.phase == PhaseCode::Stopped))
        {
            m.arms_holding_s = Some(t_s - m.requested_s);
        }
        if m.arms_stopped_s.is_none() {
            let robot = self.robot.borrow();
            let still = ArmId::ALL
                .iter()
                .all(|&arm| robot.encoders(arm).1.iter().all(|v| v.abs() < STOPPED_RATE));
            if still {
                m.arms_stopped_s = Some(t_s - m.requested_s);
            }
        }
    }

    /// Nothing left to do: the vacuum supervisor has nothing assigned, dispatched or running,
    /// both arms are idle and a detection set was processed since the last attempt ended (or,
    /// with an emergency stop, its reaction is measured).
    pub fn finished(&self) -> bool {
        if let Some(m) = &self.estop {
            return m.commanded_s.is_some()
                && m.valves_closed_s.is_some()
                && m.arms_holding_s.is_some()
                && m.arms_stopped_s.is_some();
        }
        let arms_idle = self
            .arm_states
            .iter()
            .all(|s| s.is_some_and(|s| s.phase == PhaseCode::Idle));
        arms_idle && self.vacuum.is_idle() && self.last_replan_ns > self.last_attempt_end_ns
    }

    /// Ends the episode: classifies the attempts and collects the outcome.
    pub fn finish(mut self, truncated: bool) -> EpisodeOutcome {
        let end_ns = self.clock.now_ns();
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
