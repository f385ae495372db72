//! Property tests of what the vacuum supervisor and the arms read from shared memory: a small
//! stack of the real transport-free nodes (`VacuumNode`, both `ArmNode`s) wired
//! as the processes wire them, around a plant (servos that follow their set-points, valves that
//! take time to move, cups that seal at an apple), where every message between them passes a
//! "wire" that may corrupt it: any bit pattern in any field (NaN, infinities, unknown codes,
//! lengths past their arrays), for one tick or many, or lose it.
//!
//! Whatever arrives, no node panics and nothing unsafe is commanded:
//! - every servo set-point is finite and inside the Table 1 joint limits, every feed-forward
//!   rate finite and inside the rate limits;
//! - while the emergency stop is read as engaged, both source valves are commanded closed and
//!   both arms hold;
//! - a source valve never opens beside the other arm's open, unsealed one, and both are never
//!   open with neither sealed for more than one control period (the safety monitor's rules).
//!
//! Payloads are corrupted through their raw bytes (`Payload` makes every bit pattern a valid
//! value), so the properties hold whatever the field types of the payloads become.

use harvest_arm::node::{
    ArmNode, ArmNodeConfig, ArmNodeInput, EncoderSample, OtherArmInput, ServoOrder, pick_reachable,
};
use harvest_ipc::Payload;
use harvest_ipc::payloads::{
    AppleDetection, AppleDetections, ArmState, ArmTarget, EmergencyStop, VacuumState, ValveGrant,
    ValveRequest,
};
use harvest_robot_model::ArmId;
use harvest_robot_model::joint::JointPosition;
use harvest_robot_model::kinematics::forward;
use harvest_robot_model::params::ArmId as ArmNumber;
use harvest_robot_model::params::ArmParams;
use harvest_vacuum::node::{
    BoardReadings, VacuumNode, VacuumNodeConfig, VacuumNodeEvent, VacuumNodeInput,
};
use harvest_vacuum::policy::PolicyKind;
use harvest_vacuum::pressure::AttachmentState;
use proptest::prelude::*;

/// Cases per property; each case runs `TICKS` control periods of three nodes.
const CASES: u32 = 40;
/// 3 s at 200 Hz: long enough for approaches, attachments and releases to start.
const TICKS: usize = 600;
const TICK_NS: u64 = 5_000_000;
const START_NS: u64 = 10_000_000_000;
/// Perception publishes every 20 control periods (10 Hz).
const DETECTION_EVERY: usize = 20;
/// Valve travel, control periods (50 ms).
const VALVE_TRAVEL_TICKS: usize = 10;
const ARMS: [ArmId; 2] = [ArmId::Arm1, ArmId::Arm2];
/// The same arms as the arm crate names them.
const ARM_NUMBERS: [ArmNumber; 2] = [ArmNumber::Arm1, ArmNumber::Arm2];

/// Bit patterns that break numeric code: NaN (both signs), infinities, zeros, extremes,
/// denormals, plausible values, small and huge integers, pairs of special `f32`s.
const WILD: &[u64] = &[
    0x7ff8_0000_0000_0000, // NaN
    0xfff8_0000_0000_0001, // -NaN with payload
    0x7ff0_0000_0000_0000, // +inf
    0xfff0_0000_0000_0000, // -inf
    0,
    0x8000_0000_0000_0000, // -0.0
    0x7fef_ffff_ffff_ffff, // f64::MAX
    0xffef_ffff_ffff_ffff, // f64::MIN
    1,                     // smallest denormal (also the integer 1)
    2,
    3,
    4,
    5,
    6,
    255,
    256,
    0xffff_ffff,
    u64::MAX,
    0x3ff0_0000_0000_0000, // 1.0
    0xbff0_0000_0000_0000, // -1.0
    0x3ff8_0000_0000_0000, // 1.5
    0x41cd_cd65_0000_0000, // 1e9
    0x7fc0_0000_7fc0_0000, // f32 NaN, NaN
    0xff80_0000_7f80_0000, // f32 +inf, -inf
    0x442f_0000_450f_c000, // f32 2300, 700
    0x7149_f2ca_c348_0000, // f32 -200, 1e30
];

fn wild_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        3 => prop::sample::select(WILD),
        1 => any::<u64>(),
    ]
}

/// What the wire does to one message.
#[derive(Debug, Clone)]
enum Damage {
    /// One aligned 8-byte slot overwritten.
    Slot(prop::sample::Index, u64),
    /// One byte overwritten.
    Byte(prop::sample::Index, u8),
    /// Every slot overwritten with wild values (a payload of garbage).
    Fill(u64),
    /// The message does not arrive this tick (the reader keeps its previous one).
    Lost,
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        3 => (any::<prop::sample::Index>(), wild_u64()).prop_map(|(i, v)| Damage::Slot(i, v)),
        2 => (any::<prop::sample::Index>(), any::<u8>()).prop_map(|(i, v)| Damage::Byte(i, v)),
        2 => any::<u64>().prop_map(Damage::Fill),
        1 => Just(Damage::Lost),
    ]
}

/// The channels between the nodes (and the board's readings).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Wire {
    Detections,
    Target(usize),
    Grant(usize),
    VacuumState,
    ArmState(usize),
    ValveRequest(usize),
    EmergencyStop,
    BoardReadings,
    /// An arm's encoder feedback (the servo driver's hardware channel).
    Encoders(usize),
}

const WIRES: [Wire; 14] = [
    Wire::Detections,
    Wire::Target(0),
    Wire::Target(1),
    Wire::Grant(0),
    Wire::Grant(1),
    Wire::VacuumState,
    Wire::ArmState(0),
    Wire::ArmState(1),
    Wire::ValveRequest(0),
    Wire::ValveRequest(1),
    Wire::EmergencyStop,
    Wire::BoardReadings,
    Wire::Encoders(0),
    Wire::Encoders(1),
];

/// Encoder feedback as the wire delivers it: damage lands on the joint positions and rates.
fn encoders(sample: EncoderSample, damage: Option<&Damage>) -> Option<EncoderSample> {
    let mut sample = sample;
    let mut values: Vec<f64> = sample
        .position
        .iter()
        .chain(&sample.velocity)
        .copied()
        .collect();
    match damage {
        None => {}
        Some(Damage::Lost) => return None,
        Some(Damage::Byte(at, value)) => {
            let at = at.index(values.len());
            values[at] = f64::from(*value);
        }
        Some(Damage::Slot(at, value)) => {
            let at = at.index(values.len());
            values[at] = f64::from_bits(*value);
        }
        Some(Damage::Fill(seed)) => {
            for (v, bits) in values.iter_mut().zip(wild_stream(*seed)) {
                *v = f64::from_bits(bits);
            }
        }
    }
    sample.position.copy_from_slice(&values[..4]);
    sample.velocity.copy_from_slice(&values[4..]);
    Some(sample)
}

/// `damage` applied to `wire` from tick `start` for `ticks` ticks.
#[derive(Debug, Clone)]
struct Fault {
    start: usize,
    ticks: usize,
    wire: Wire,
    damage: Damage,
}

fn fault() -> impl Strategy<Value = Fault> {
    (
        0..TICKS,
        prop_oneof![3 => Just(1usize), 1 => 1usize..200],
        prop::sample::select(WIRES.to_vec()),
        damage(),
    )
        .prop_map(|(start, ticks, wire, damage)| Fault {
            start,
            ticks,
            wire,
            damage,
        })
}

fn damage_at(faults: &[Fault], wire: Wire, tick: usize) -> Option<&Damage> {
    faults
        .iter()
        .find(|f| f.wire == wire && (f.start..f.start + f.ticks).contains(&tick))
        .map(|f| &f.damage)
}

/// The raw bytes of a payload (every bit pattern of them is a valid value).
fn bytes_of<T: Payload>(value: &mut T) -> &mut [u8] {
    // SAFETY: `value` is a valid, uniquely borrowed `T` of `size_of::<T>()` bytes, and every bit
    // pattern is a valid `T` (the `Payload` contract), so any bytes written leave a valid `T`.
    unsafe {
        std::slice::from_raw_parts_mut((value as *mut T).cast::<u8>(), std::mem::size_of::<T>())
    }
}

/// A deterministic stream of wild values (for `Damage::Fill`).
fn wild_stream(seed: u64) -> impl Iterator<Item = u64> {
    let mut state = seed | 1;
    std::iter::repeat_with(move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        if state.is_multiple_of(4) {
            state
        } else {
            WILD[(state >> 8) as usize % WILD.len()]
        }
    })
}

/// Applies `damage` to the bytes of `value` (a copy in a fresh heap box, as a reader of loaned
/// shared memory sees it); `None` when the message is lost.
fn through_wire<T: Payload + Copy>(value: &T, damage: Option<&Damage>) -> Option<Box<T>> {
    let mut boxed = harvest_ipc::payload::boxed_zeroed::<T>();
    *boxed = *value;
    let bytes = bytes_of(&mut *boxed);
    match damage {
        None => {}
        Some(Damage::Lost) => return None,
        Some(Damage::Byte(at, value)) => {
            let at = at.index(bytes.len());
            bytes[at] = *value;
        }
        Some(Damage::Slot(at, value)) => {
            let slots = bytes.len() / 8;
            let start = at.index(slots.max(1)) * 8;
            for (byte, source) in bytes[start..].iter_mut().zip(value.to_le_bytes()) {
                *byte = source;
            }
        }
        Some(Damage::Fill(seed)) => {
            for (chunk, value) in bytes.chunks_mut(8).zip(wild_stream(*seed)) {
                for (byte, source) in chunk.iter_mut().zip(value.to_le_bytes()) {
                    *byte = source;
                }
            }
        }
    }
    Some(boxed)
}

/// Whether the emergency stop payload reads as engaged, as the processes read it (`engaged`
/// not 0), through its raw byte so the field's type does not matter.
fn engaged(stop: &mut EmergencyStop) -> bool {
    bytes_of(stop)[std::mem::offset_of!(EmergencyStop, engaged)] != 0
}

/// The apples of the test orchard, robot frame (m), radius 3.5 cm.
fn apples() -> impl Strategy<Value = Vec<[f64; 3]>> {
    prop::collection::vec(
        (1.30f64..1.65, -0.35f64..0.35, 0.30f64..0.75).prop_map(|(x, y, z)| [x, y, z]),
        1..8,
    )
}

const RADIUS_M: f64 = 0.035;

fn detections(apples: &[[f64; 3]], capture_ns: u64, seq: u64) -> AppleDetections {
    let mut set = AppleDetections::default();
    set.header.msg_seq = seq;
    set.header.capture_ns = capture_ns;
    set.source_frame_seq = seq;
    set.source_capture_ns = capture_ns;
    for (k, position) in apples.iter().enumerate() {
        let _ = set.apples.push(AppleDetection {
            apple_id: k as u32 + 1,
            position_in_robot_m: *position,
            position_in_camera_m: *position,
            radius_m: RADIUS_M,
            confidence: 0.9,
            ..AppleDetection::default()
        });
    }
    set
}

/// One arm's plant: servos that follow their set-point, the cup.
#[derive(Debug, Clone, Copy)]
struct ArmPlant {
    q: [f64; 4],
    v: [f64; 4],
    /// An apple seals the cup (from the moment the open cup reaches it until the valve closes).
    holding: bool,
}

/// The stack: the nodes, the latest sample on every channel, the plant.
struct Stack {
    vacuum: VacuumNode,
    arms: [ArmNode; 2],
    params: [ArmParams; 2],
    plants: [ArmPlant; 2],
    /// Commanded valves 1-4 and the tick each last changed.
    valves: [bool; 4],
    valve_changed: [usize; 4],
    apples: Vec<[f64; 3]>,
    targets: [Option<ArmTarget>; 2],
    grants: [Option<ValveGrant>; 2],
    vacuum_state: Option<VacuumState>,
    arm_states: [Option<ArmState>; 2],
    requests: [Option<ValveRequest>; 2],
    /// Safety bookkeeping: each source valve as commanded the previous tick.
    open_before: [bool; 2],
    both_open_unsealed_ticks: usize,
    valve_openings: usize,
    /// What each reader last took from each channel (a lost message leaves it in place, as a
    /// subscriber of a history-1 channel keeps its last sample).
    delivered: Delivered,
}

/// The last sample each reader took, per channel.
#[derive(Default)]
struct Delivered {
    stop: Option<bool>,
    states_to_vacuum: [Option<Box<ArmState>>; 2],
    requests: [Option<Box<ValveRequest>>; 2],
    vacuum_state: Option<Box<VacuumState>>,
    targets: [Option<Box<ArmTarget>>; 2],
    grants: [Option<Box<ValveGrant>>; 2],
    states_to_arms: [Option<Box<ArmState>>; 2],
    other_targets: [Option<Box<ArmTarget>>; 2],
}

/// Delivers `sent` (if any) through the wire into `slot`; a lost message leaves `slot` as it
/// was.
fn deliver<T: Payload + Copy>(
    slot: &mut Option<Box<T>>,
    sent: Option<&T>,
    damage: Option<&Damage>,
) {
    if let Some(value) = sent
        && let Some(received) = through_wire(value, damage)
    {
        *slot = Some(received);
    }
}

impl Stack {
    fn new(policy: PolicyKind, apples: Vec<[f64; 3]>) -> Self {
        let arm_config = ArmNodeConfig::default();
        let reach: harvest_vacuum::node::Reachability = Box::new(move |arm, centre, radius_m| {
            pick_reachable(ARM_NUMBERS[arm.index()], *centre, radius_m, &arm_config)
        });
        let vacuum = VacuumNode::new(
            VacuumNodeConfig {
                policy,
                ..VacuumNodeConfig::default()
            },
            reach,
        )
        .expect("vacuum node");
        let params = ARM_NUMBERS.map(ArmParams::for_arm);
        Self {
            vacuum,
            arms: ARM_NUMBERS.map(|arm| ArmNode::new(arm, arm_config).expect("arm node")),
            params,
            plants: params.map(|p| ArmPlant {
                q: p.home.to_array(),
                v: [0.0; 4],
                holding: false,
            }),
            valves: [false, true, false, true],
            valve_changed: [0; 4],
            apples,
            targets: [None; 2],
            grants: [None; 2],
            vacuum_state: None,
            arm_states: [None; 2],
            requests: [None; 2],
            open_before: [false; 2],
            both_open_unsealed_ticks: 0,
            valve_openings: 0,
            delivered: Delivered::default(),
        }
    }

    /// Updates the cups (an open, settled cup at an apple's picking point seals; a closed valve
    /// lets go) and returns the board's readings: valves as commanded (in transit while they
    /// move), arm tube vacuum 2300 sealed, 700 open, 400 moving, 0 vented; the source at 2400.
    fn readings(&mut self, tick: usize, now_ns: u64, damage: Option<&Damage>) -> BoardReadings {
        let in_transit: [bool; 4] = std::array::from_fn(|i| {
            tick.saturating_sub(self.valve_changed[i]) < VALVE_TRAVEL_TICKS
        });
        let mut pressure = [0.0f32; 2];
        for (arm, arm_pressure) in pressure.iter_mut().enumerate() {
            let inlet = 2 * arm;
            let plant = &mut self.plants[arm];
            if !self.valves[inlet] {
                plant.holding = false;
                continue;
            }
            if in_transit[inlet] {
                *arm_pressure = 400.0;
                continue;
            }
            let cup = forward(&self.params[arm].links, &JointPosition::from_array(plant.q));
            let at_apple = self.apples.iter().any(|apple| {
                let pick = [apple[0] - RADIUS_M, apple[1], apple[2]];
                (0..3).map(|k| (pick[k] - cup[k]).powi(2)).sum::<f64>() < 0.015f64.powi(2)
            });
            plant.holding |= at_apple;
            *arm_pressure = if plant.holding { 2300.0 } else { 700.0 };
        }
        let mut readings = BoardReadings {
            stamp_ns: now_ns,
            valve_open: self.valves,
            valve_in_transit: in_transit,
            pressure_mmh2o: [pressure[0], pressure[1], 2400.0],
        };
        // Readings come from the board driver (the serial line, or the simulator's hardware
        // channel): damage lands on the pressures and valve flags.
        match damage {
            None | Some(Damage::Lost) => {}
            Some(Damage::Byte(at, value)) => {
                let at = at.index(4);
                readings.valve_open[at] = value & 1 != 0;
                readings.valve_in_transit[at] = value & 2 != 0;
            }
            Some(Damage::Slot(at, value)) => {
                let at = at.index(3);
                readings.pressure_mmh2o[at] = f32::from_bits(*value as u32);
            }
            Some(Damage::Fill(seed)) => {
                let mut stream = wild_stream(*seed);
                for p in &mut readings.pressure_mmh2o {
                    *p = f32::from_bits(stream.next().unwrap_or(0) as u32);
                }
            }
        }
        readings
    }

    /// One control period of the whole stack; checks the safety properties.
    fn tick(&mut self, tick: usize, faults: &[Fault]) -> Result<(), TestCaseError> {
        let now_ns = START_NS + tick as u64 * TICK_NS;
        let damage = |wire| damage_at(faults, wire, tick);

        let stop = EmergencyStop::default();
        if let Some(mut received) = through_wire(&stop, damage(Wire::EmergencyStop)) {
            self.delivered.stop = Some(engaged(&mut received));
        }
        let estop = self.delivered.stop.unwrap_or(false);

        // The vacuum supervisor.
        let detections = tick.is_multiple_of(DETECTION_EVERY).then(|| {
            detections(
                &self.apples,
                now_ns.saturating_sub(60_000_000),
                (tick / DETECTION_EVERY) as u64 + 1,
            )
        });
        let detections = detections.and_then(|d| through_wire(&d, damage(Wire::Detections)));
        for i in 0..2 {
            deliver(
                &mut self.delivered.states_to_vacuum[i],
                self.arm_states[i].as_ref(),
                damage(Wire::ArmState(i)),
            );
            deliver(
                &mut self.delivered.requests[i],
                self.requests[i].as_ref(),
                damage(Wire::ValveRequest(i)),
            );
        }
        let readings = self.readings(tick, now_ns, damage(Wire::BoardReadings));
        let states = &self.delivered.states_to_vacuum;
        let requests = &self.delivered.requests;
        let input = VacuumNodeInput {
            now_ns,
            arm_states: [states[0].as_deref(), states[1].as_deref()],
            valve_requests: [requests[0].as_deref(), requests[1].as_deref()],
            readings: (!matches!(damage(Wire::BoardReadings), Some(Damage::Lost)))
                .then_some(readings),
            detections: detections.as_deref(),
            emergency_stop: estop,
        };
        let out = self.vacuum.step(&input).clone();
        self.valve_openings += out
            .events
            .iter()
            .filter(|e| matches!(e, VacuumNodeEvent::ValveOpened { .. }))
            .count();

        // Valve safety, from the commands and the supervisor's own attachment inference.
        let open = [out.valve_commands[0], out.valve_commands[2]];
        let sealed = ARMS.map(|arm| self.vacuum.attachment(arm) == AttachmentState::Sealed);
        if estop {
            prop_assert!(
                !open[0] && !open[1],
                "tick {tick}: valve open under the emergency stop"
            );
        }
        for arm in 0..2 {
            let other = 1 - arm;
            let opened = open[arm] && !self.open_before[arm];
            prop_assert!(
                !(opened && self.open_before[other] && open[other] && !sealed[other]),
                "tick {tick}: arm {} opened beside arm {}'s open, unsealed valve",
                arm + 1,
                other + 1
            );
        }
        if open[0] && open[1] && !sealed[0] && !sealed[1] {
            self.both_open_unsealed_ticks += 1;
        } else {
            self.both_open_unsealed_ticks = 0;
        }
        prop_assert!(
            self.both_open_unsealed_ticks <= 1,
            "tick {tick}: both valves open, neither sealed, for {} periods",
            self.both_open_unsealed_ticks
        );
        self.open_before = open;
        for (i, command) in out.valve_commands.iter().enumerate() {
            if *command != self.valves[i] {
                self.valves[i] = *command;
                self.valve_changed[i] = tick;
            }
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

        // The arms.
        deliver(
            &mut self.delivered.vacuum_state,
            self.vacuum_state.as_ref(),
            damage(Wire::VacuumState),
        );
        for arm in 0..2 {
            let other = 1 - arm;
            deliver(
                &mut self.delivered.targets[arm],
                self.targets[arm].as_ref(),
                damage(Wire::Target(arm)),
            );
            deliver(
                &mut self.delivered.grants[arm],
                self.grants[arm].as_ref(),
                damage(Wire::Grant(arm)),
            );
            deliver(
                &mut self.delivered.states_to_arms[arm],
                self.arm_states[other].as_ref(),
                damage(Wire::ArmState(other)),
            );
            deliver(
                &mut self.delivered.other_targets[arm],
                self.targets[other].as_ref(),
                damage(Wire::Target(other)),
            );
            let delivered = &self.delivered;
            let vacuum_state = delivered.vacuum_state.as_deref();
            let target = delivered.targets[arm].as_deref();
            let grant = delivered.grants[arm].as_deref();
            let other_state = delivered.states_to_arms[arm].as_deref();
            let other_target = delivered.other_targets[arm].as_deref();
            let plant = self.plants[arm];
            let input = ArmNodeInput {
                now_ns,
                feedback: encoders(
                    EncoderSample {
                        capture_ns: now_ns,
                        position: plant.q,
                        velocity: plant.v,
                    },
                    damage(Wire::Encoders(arm)),
                ),
                target,
                vacuum: vacuum_state,
                grant,
                other_arm: other_state.map(|state| OtherArmInput {
                    state,
                    target: other_target,
                }),
                emergency_stop: estop,
            };
            let out = self.arms[arm].step(&input).clone();
            let params = &self.params[arm];
            match out.servo {
                ServoOrder::Hold => self.plants[arm].v = [0.0; 4],
                ServoOrder::Track { position, velocity } => {
                    prop_assert!(
                        !estop,
                        "tick {tick}: arm {} moves under the emergency stop",
                        arm + 1
                    );
                    let lo = params.position_limits.min.to_array();
                    let hi = params.position_limits.max.to_array();
                    let rate = params.rate_limits.to_array();
                    for j in 0..4 {
                        prop_assert!(
                            position[j].is_finite() && (lo[j]..=hi[j]).contains(&position[j]),
                            "tick {tick}: arm {} joint {j} set-point {} outside [{}, {}]",
                            arm + 1,
                            position[j],
                            lo[j],
                            hi[j]
                        );
                        prop_assert!(
                            velocity[j].is_finite()
                                && velocity[j].abs() <= rate[j].abs() * 1.000_001,
                            "tick {tick}: arm {} joint {j} rate {} beyond {}",
                            arm + 1,
                            velocity[j],
                            rate[j]
                        );
                    }
                    self.plants[arm].q = position;
                    self.plants[arm].v = velocity;
                }
            }
            self.requests[arm] = Some(out.valve_request);
            self.arm_states[arm] = Some(out.state);
        }
        Ok(())
    }
}

fn policy() -> impl Strategy<Value = PolicyKind> {
    prop_oneof![
        Just(PolicyKind::Baseline),
        Just(PolicyKind::V2023),
        Just(PolicyKind::V2024),
    ]
}

/// The bench itself works: without faults the stack dispatches apples and opens valves, so the
/// properties below judge a stack that really moves and attaches.
#[test]
fn the_stack_without_faults_opens_valves_at_apples() {
    let apples = vec![[1.487, -0.05, 0.50], [1.45, 0.20, 0.45]];
    for policy in [PolicyKind::Baseline, PolicyKind::V2023, PolicyKind::V2024] {
        let mut stack = Stack::new(policy, apples.clone());
        for tick in 0..TICKS {
            stack.tick(tick, &[]).expect("safe without faults");
        }
        assert!(stack.valve_openings > 0, "{policy:?}: no valve opened");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(CASES))]

    /// Any corruption of any message between the nodes, for one tick or many: no panic, no
    /// unsafe motion, no unsafe valve.
    #[test]
    fn corrupted_messages_never_cause_unsafe_commands(
        policy in policy(),
        apples in apples(),
        faults in prop::collection::vec(fault(), 0..40),
    ) {
        let mut stack = Stack::new(policy, apples);
        for tick in 0..TICKS {
            stack.tick(tick, &faults)?;
        }
    }

    /// Every message on one channel replaced by garbage for the whole run.
    #[test]
    fn a_channel_of_garbage_never_causes_unsafe_commands(
        policy in policy(),
        apples in apples(),
        wire in prop::sample::select(WIRES.to_vec()),
        seed in any::<u64>(),
    ) {
        let mut stack = Stack::new(policy, apples);
        let faults = [Fault { start: 0, ticks: TICKS, wire, damage: Damage::Fill(seed) }];
        for tick in 0..TICKS {
            stack.tick(tick, &faults)?;
        }
    }
}

/// Found by the property below: one garbage `arm1/state` sample (arm id 0, phase code idle)
/// made the baseline policy believe arm 1 had finished and send arm 2 out beside it; the
/// baseline grants valves without looking at the other arm, so at tick 319 arm 1's valve opened
/// beside arm 2's open, unsealed one. The vacuum node now refuses that opening whatever the
/// policy and the arm reports say.
#[test]
fn a_garbage_arm_state_does_not_open_a_valve_beside_an_unsealed_one() {
    let apples = vec![
        [1.4973826294055734, 0.0, 0.395476411943217],
        [1.3, 0.0, 0.3],
        [1.3, -0.22363707588214912, 0.46039259634335744],
    ];
    let faults = [Fault {
        start: 43,
        ticks: 1,
        wire: Wire::ArmState(0),
        damage: Damage::Fill(4735234467619320760),
    }];
    let mut stack = Stack::new(PolicyKind::Baseline, apples);
    for tick in 0..TICKS {
        stack.tick(tick, &faults).expect("safe");
    }
    assert!(
        stack.valve_openings > 0,
        "the case still reaches the valves"
    );
}
