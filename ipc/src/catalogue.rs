//! The channel catalogue: every channel of the stack, declared once with its topic, payload type
//! and QoS. No other code names a service.
//!
//! QoS policy: every channel uses iceoryx2's safe overflow (a full subscriber buffer drops its
//! oldest sample), so no subscriber, the recorder included, can ever block a publisher; drops
//! are seen as `msg_seq` gaps and counted by [`crate::Subscriber`]. Buffers are sized per
//! channel for the subscribers that must not lose messages (the recorder asks for the maximum).
//!
//! Writer policy: a channel accepts as many publishers as it has legitimate writers. The presets
//! allow one ([`Qos::max_publishers`] = 1): a second process creating a publisher on such a
//! channel (a stray `harvest arm --id 1` beside a running stack's arm 1, a second stack in the
//! same domain) fails at port creation, naming the channel, instead of becoming a second voice
//! on the servos or valves. Channels with several writers say so with
//! [`Qos::with_max_publishers`] and name their writers: `vacuum/valve_request` (the two arms),
//! `harvest/events` (arms and vacuum supervisor), `system/health` (every process),
//! `operator/command` and `operator/mark` (`harvest ctl`, the console). A crashed
//! writer's port is removed by the supervisor's stale-resource cleanup before its restart
//! ([`crate::cleanup::remove_dead_nodes`]), so restarts still find the slot free. Replaying a
//! recording into a domain where the stack runs is refused per channel for the channels the
//! stack writes (`harvest replay` reports them as skipped with the publisher-limit error).

use crate::arm_id::ArmId;
use crate::payload::Payload;
use crate::payloads::*;
use std::marker::PhantomData;

/// Quality of service of one channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// Samples a late-joining subscriber receives on connect.
    pub history_size: usize,
    /// Largest buffer a subscriber may ask for.
    pub subscriber_max_buffer_size: usize,
    /// Buffer used when a subscriber does not ask for a specific one.
    pub default_buffer_size: usize,
    /// Drop the oldest sample when a subscriber's buffer is full (never block the publisher).
    pub safe_overflow: bool,
    /// Publishers the channel accepts at once: its legitimate writers (1 in every preset; see
    /// the module's writer policy). Also the event companion's notifier limit.
    pub max_publishers: usize,
    /// Subscribers the channel accepts at once (also the event companion's listener limit).
    pub max_subscribers: usize,
    /// Nodes (processes) that may have the channel's service open at once.
    pub max_nodes: usize,
    /// Samples one publisher may hold loaned at once.
    pub max_loans: usize,
}

impl Qos {
    /// Small messages: generous buffers, many readers, one writer.
    pub const SMALL: Self = Self {
        history_size: 0,
        subscriber_max_buffer_size: 256,
        default_buffer_size: 64,
        safe_overflow: true,
        max_publishers: 1,
        max_subscribers: 8,
        max_nodes: 16,
        max_loans: 2,
    };
    /// Latched state (late joiners get the last value), one writer.
    pub const STATE: Self = Self {
        history_size: 1,
        ..Self::SMALL
    };
    /// Multi-megabyte frames. iceoryx2 pre-allocates each publisher's data segment for the
    /// worst case, [`Self::data_segment_samples`] x payload size, so every buffer slot costs a
    /// whole frame of shared memory in every subscriber slot. Most readers want only the
    /// newest frame (perception, the viewers, the benchmarks: buffer 1-2), and the recorder,
    /// which wants every frame, copies each one out at once into its own writer queue, so a
    /// short buffer covers its receive loop: many subscribers with short buffers, not a few
    /// with long ones. 8 subscribers x (3 + 2 borrowed) + 2 loans = 42 frames, as many as the
    /// earlier 4 x (8 + 2) + 2: the stack's four readers (perception, recorder, Foxglove
    /// bridge, console) plus four tools at once (a benchmark, a second viewer, a monitor, a
    /// replay check) in the same shared memory. A ninth subscriber is refused at port creation
    /// ([`crate::error::OpenChannelError::PortLimit`], naming the channel and the limit) and
    /// changes nothing for the others. One writer.
    pub const FRAMES: Self = Self {
        history_size: 0,
        subscriber_max_buffer_size: 3,
        default_buffer_size: 2,
        safe_overflow: true,
        max_publishers: 1,
        max_subscribers: 8,
        // The subscribers' nodes, the publisher's, and room for a restarted process's node
        // before its stale one is cleaned.
        max_nodes: 12,
        max_loans: 2,
    };

    /// This QoS for a channel with `max_publishers` legitimate writers (name them in the
    /// channel's description).
    pub const fn with_max_publishers(self, max_publishers: usize) -> Self {
        Self {
            max_publishers,
            ..self
        }
    }

    /// Whether exactly one process may write the channel (a second publisher is refused).
    pub const fn single_writer(&self) -> bool {
        self.max_publishers == 1
    }

    /// Samples in each publisher's data segment, as iceoryx2 0.10 sizes it
    /// (`required_amount_of_samples_per_data_segment`): subscribers x (buffer + borrowed) +
    /// history + loans. Times the payload size, that is the shared memory one publisher holds.
    pub const fn data_segment_samples(&self) -> usize {
        self.max_subscribers * (self.subscriber_max_buffer_size + SUBSCRIBER_MAX_BORROWED_SAMPLES)
            + self.history_size
            + self.max_loans
    }
}

/// Samples one subscriber may hold at once (set on every service; iceoryx2's default). Two,
/// because [`crate::Subscriber::receive_latest`] takes the next sample before it lets go of the
/// one before.
pub const SUBSCRIBER_MAX_BORROWED_SAMPLES: usize = 2;

/// Which layer a channel belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layer {
    /// Between the stack's processes.
    Stack,
    /// Between a device driver and its device (here: the simulator standing in for hardware).
    Hardware,
    /// Ground truth for evaluation only; no stack process may subscribe.
    Evaluation,
}

/// A channel's static description (type-erased).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChannelSpec {
    /// Topic name, also the MCAP topic: `camera/rgbd`, `arm1/state`.
    pub topic: &'static str,
    /// Whether the channel is between processes, between a driver and its device, or ground truth.
    pub layer: Layer,
    /// The payload's stable type name ([`Payload::TYPE_NAME`]), also the MCAP schema name.
    pub type_name: &'static str,
    /// The payload's layout version ([`Payload::VERSION`]); raised on every layout change.
    pub version: u32,
    /// Buffers, history and port limits of the channel's service.
    pub qos: Qos,
    /// One line for people: what flows, its frame or units, its rate and its writers.
    pub description: &'static str,
}

impl ChannelSpec {
    /// The iceoryx2 service name of this channel (the domain lives in the file prefix).
    pub fn service_name(&self) -> String {
        format!("harvest/{}", self.topic)
    }
}

/// A typed channel of the catalogue.
pub struct Channel<T: Payload> {
    /// Topic, layer, payload type and QoS of the channel.
    pub spec: ChannelSpec,
    payload: PhantomData<fn() -> T>,
}

impl<T: Payload> Clone for Channel<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T: Payload> Copy for Channel<T> {}

impl<T: Payload> std::fmt::Debug for Channel<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.spec.fmt(f)
    }
}

impl<T: Payload> Channel<T> {
    const fn new(topic: &'static str, qos: Qos, description: &'static str) -> Self {
        Self::in_layer(Layer::Stack, topic, qos, description)
    }

    const fn in_layer(
        layer: Layer,
        topic: &'static str,
        qos: Qos,
        description: &'static str,
    ) -> Self {
        Self {
            spec: ChannelSpec {
                topic,
                layer,
                type_name: T::TYPE_NAME,
                version: T::VERSION,
                qos,
                description,
            },
            payload: PhantomData,
        }
    }

    /// An ad-hoc channel that is **not part of the stack catalogue**: for benchmarks and
    /// evaluation tools that need a channel of their own (e.g. `harvest bench ipc`'s payload-size
    /// sweep). It is in [`Layer::Evaluation`], is not visited by [`visit_all`] (so it is never
    /// recorded, replayed or listed), and no stack process opens it. The caller picks a topic
    /// that no catalogue channel uses (by convention under `bench/`); it becomes the service
    /// `harvest/<topic>` like any other channel.
    pub const fn ad_hoc(topic: &'static str, qos: Qos) -> Self {
        Self::in_layer(
            Layer::Evaluation,
            topic,
            qos,
            "ad-hoc channel (not part of the stack catalogue)",
        )
    }
}

/// Registered RGB-D frames, written by the camera driver (`harvest camera`), read by perception,
/// the recorder and the Foxglove bridge.
pub const CAMERA_RGBD: Channel<RgbdFrame> = Channel::new(
    "camera/rgbd",
    Qos::FRAMES,
    "registered RGB-D frames of the ToF camera (1920x1080 RGB8 + 640x480 depth mm), 30 Hz",
);
/// Apples detected in one camera frame, localized in the robot frame; written by perception, read
/// by the vacuum supervisor (target assignment), the recorder and the viewers.
pub const PERCEPTION_APPLES: Channel<AppleDetections> = Channel::new(
    "perception/apples",
    Qos::SMALL,
    "apples detected and localized in one camera frame",
);
/// Requests to scan one apple with the ALACS unit, written by perception, read by the laser
/// process.
pub const LASER_SCAN_REQUEST: Channel<LaserScanRequest> = Channel::new(
    "laser/scan_request",
    Qos::SMALL,
    "ask the ALACS unit to scan one apple",
);
/// The laser process's answer to each scan request: the fused centre, every per-image candidate
/// and the timing of the scan.
pub const LASER_SCAN_RESULT: Channel<LaserScanResult> = Channel::new(
    "laser/scan_result",
    Qos::SMALL,
    "ALACS scan result with all per-image candidates and timing",
);
/// The apple assigned to each arm (indexed by [`ArmId::index`]), latched; written by the vacuum
/// supervisor, read by that arm's process.
pub const ARM_TARGET: [Channel<ArmTarget>; 2] = [
    Channel::new("arm1/target", Qos::STATE, "apple assigned to arm 1"),
    Channel::new("arm2/target", Qos::STATE, "apple assigned to arm 2"),
];
/// Joint set-points each arm process sends to its servo driver, 200 Hz (indexed by
/// [`ArmId::index`]).
pub const ARM_COMMAND: [Channel<ArmCommand>; 2] = [
    Channel::new(
        "arm1/command",
        Qos::SMALL,
        "joint set-points for arm 1's servos, 200 Hz",
    ),
    Channel::new(
        "arm2/command",
        Qos::SMALL,
        "joint set-points for arm 2's servos, 200 Hz",
    ),
];
/// Each arm's phase, joints and end-effector pose, latched, 200 Hz; written by the arm process,
/// read by the vacuum supervisor, the safety monitor and the viewers.
pub const ARM_STATE: [Channel<ArmState>; 2] = [
    Channel::new(
        "arm1/state",
        Qos::STATE,
        "arm 1 phase, joints and end-effector, 200 Hz",
    ),
    Channel::new(
        "arm2/state",
        Qos::STATE,
        "arm 2 phase, joints and end-effector, 200 Hz",
    ),
];
/// Tick records: a recorder that joins after the node started still gets its first ticks (the
/// last 1.28 s at 200 Hz, from the channel's history), so a re-run can begin at the node's
/// first tick. Few readers: the recorder and a tool.
const TICK_RECORDS: Qos = Qos {
    history_size: 256,
    subscriber_max_buffer_size: 256,
    max_subscribers: 4,
    ..Qos::SMALL
};
/// What each arm's control node saw at every tick (the stop, the mode, its encoders, the
/// messages it read), 200 Hz; written by the arm process, read by the recorder, so that
/// `harvest replay --check` can re-run the arm on a recording.
pub const ARM_TICKS: [Channel<NodeTickRecord>; 2] = [
    Channel::new(
        "arm1/ticks",
        TICK_RECORDS,
        "arm 1's control ticks: stop, mode, encoders and the messages read, 200 Hz",
    ),
    Channel::new(
        "arm2/ticks",
        TICK_RECORDS,
        "arm 2's control ticks: stop, mode, encoders and the messages read, 200 Hz",
    ),
];
/// Valve open/close requests of the two arm processes to the vacuum supervisor.
pub const VALVE_REQUEST: Channel<ValveRequest> = Channel::new(
    "vacuum/valve_request",
    Qos::SMALL.with_max_publishers(2),
    "arms ask to open or close their valves (writers: arm1, arm2)",
);
/// The vacuum supervisor's answer (granted or refused) to each valve request.
pub const VALVE_GRANT: Channel<ValveGrant> = Channel::new(
    "vacuum/valve_grant",
    Qos::SMALL,
    "vacuum supervisor's answer to each valve request",
);
/// The vacuum system's state, latched: valves, the three pressures and the attachment inferred per
/// arm; written by the vacuum supervisor.
pub const VACUUM_STATE: Channel<VacuumState> = Channel::new(
    "vacuum/state",
    Qos::STATE,
    "valves, 3 pressures and inferred attachment per arm",
);
/// What the vacuum supervisor saw at every tick (the stop, the mode, the valve board's
/// readings, the messages it read), 200 Hz; read by the recorder for `harvest replay --check`.
pub const VACUUM_TICKS: Channel<NodeTickRecord> = Channel::new(
    "vacuum/ticks",
    TICK_RECORDS,
    "the vacuum supervisor's control ticks: stop, mode, valve board and the messages read, 200 Hz",
);
/// One writer, the owner of the stop: the executive (`harvest executive`). Anyone else who
/// must stop the robot asks the owner (operators on `operator/command`, the safety monitor on
/// `safety/violation`); nobody else can engage or release it. Read by every node that drives
/// an actuator (the arms, the vacuum supervisor, the laser, the executive itself) and by the
/// watchers (monitor, recorder, Foxglove bridge, remote link) and tools: room for 16.
pub const EMERGENCY_STOP: Channel<EmergencyStop> = Channel::new(
    "safety/emergency_stop",
    Qos {
        max_subscribers: 16,
        max_nodes: 24,
        ..Qos::STATE
    },
    "engaged: all arms stop, all valves close (writer: the executive)",
);
/// One writer, the independent safety monitor (`harvest monitor --on-violation report|stop`).
/// Readers: the executive, which engages the protective stop for a violation whose action is
/// `stop`; the recorder; `harvest up`'s summary. No history: a restarted executive must not
/// engage the stop again for a violation the operator has already released.
pub const SAFETY_VIOLATION: Channel<SafetyViolation> = Channel::new(
    "safety/violation",
    Qos::SMALL,
    "safety rules the independent monitor found broken on the live channels, with the action \
it asks for (report, or the protective stop)",
);
/// Per-apple harvest events (assigned, phases, result, rejected targets) of the arms, the vacuum
/// supervisor and the row executive; read by the recorder, `harvest up`'s summary and `eval`.
pub const HARVEST_EVENTS: Channel<HarvestEvent> = Channel::new(
    "harvest/events",
    // arm1, arm2 and the vacuum supervisor, with room for diagnostic tools.
    Qos::SMALL.with_max_publishers(6),
    "per-apple harvest events of the arms and the vacuum supervisor (assigned, phases, result, \
rejected targets with a reason)",
);
/// Every process's heartbeat (2 Hz), with its state, counters and last device error; read by the
/// supervisor, the console and the recorder.
pub const PROCESS_HEALTH: Channel<ProcessHealth> = Channel::new(
    "system/health",
    Qos {
        max_nodes: 32,
        ..Qos::SMALL.with_max_publishers(24)
    },
    "heartbeat of every process, 2 Hz (writers: every process)",
);

/// The simulated (or real) camera device's frame output, read by the camera driver.
pub const HW_CAMERA_RGBD: Channel<RgbdFrame> = Channel::in_layer(
    Layer::Hardware,
    "hw/camera/rgbd",
    Qos {
        max_subscribers: 2,
        subscriber_max_buffer_size: 8,
        max_nodes: 8,
        ..Qos::FRAMES
    },
    "frames as the ToF camera device delivers them to its driver",
);

/// Servo set-points from each arm's servo driver to its device (the simulator stands in), 200 Hz.
pub const HW_ARM_SERVO: [Channel<ServoSetpoint>; 2] = [
    Channel::in_layer(
        Layer::Hardware,
        "hw/arm1/servo",
        Qos::SMALL,
        "servo set-points to arm 1, 200 Hz",
    ),
    Channel::in_layer(
        Layer::Hardware,
        "hw/arm2/servo",
        Qos::SMALL,
        "servo set-points to arm 2, 200 Hz",
    ),
];
/// Encoder feedback of each arm device to its driver, latched, 200 Hz.
pub const HW_ARM_ENCODERS: [Channel<EncoderFeedback>; 2] = [
    Channel::in_layer(
        Layer::Hardware,
        "hw/arm1/encoders",
        Qos::STATE,
        "arm 1 encoder feedback, 200 Hz",
    ),
    Channel::in_layer(
        Layer::Hardware,
        "hw/arm2/encoders",
        Qos::STATE,
        "arm 2 encoder feedback, 200 Hz",
    ),
];
/// Valve commands from the valve-board driver to the (simulated) valve board, latched.
pub const HW_VALVE_COMMAND: Channel<ValveBoardCommand> = Channel::in_layer(
    Layer::Hardware,
    "hw/valves/command",
    Qos::STATE,
    "valve commands to the valve board",
);
/// Valve states and the three pressures the (simulated) valve board reports, 200 Hz.
pub const HW_VALVE_READINGS: Channel<ValveBoardReadings> = Channel::in_layer(
    Layer::Hardware,
    "hw/valves/readings",
    Qos::STATE,
    "valve states and the 3 pressures from the valve board, 200 Hz",
);
/// Slide, laser and capture commands from the ALACS driver to its device.
pub const HW_ALACS_COMMAND: Channel<AlacsCommand> = Channel::in_layer(
    Layer::Hardware,
    "hw/alacs/command",
    Qos::SMALL,
    "ALACS slide, laser and capture commands",
);
/// The ALACS device's answers: one 1440x1080 RGB image per capture, with the slide position.
pub const HW_ALACS_IMAGE: Channel<AlacsImage> = Channel::in_layer(
    Layer::Hardware,
    "hw/alacs/image",
    Qos {
        max_subscribers: 2,
        subscriber_max_buffer_size: 8,
        max_nodes: 8,
        ..Qos::FRAMES
    },
    "ALACS device answers with the 1440x1080 RGB image",
);
/// In-out and up-down targets (or stop) from the platform driver to the platform movement
/// module.
pub const HW_PLATFORM_COMMAND: Channel<PlatformCommand> = Channel::in_layer(
    Layer::Hardware,
    "hw/platform/command",
    Qos::STATE,
    "in-out and up-down targets (or stop) to the platform movement module",
);
/// The platform module's stage positions and motion state, latched, 50 Hz.
pub const HW_PLATFORM_FEEDBACK: Channel<PlatformFeedback> = Channel::in_layer(
    Layer::Hardware,
    "hw/platform/feedback",
    Qos::STATE,
    "platform stage positions and motion state, 50 Hz",
);
// The field row: the tractor pulling the trailer along the row.
/// The target along the row (or stop) from the tractor driver to the tractor pulling the trailer.
pub const HW_TRACTOR_COMMAND: Channel<TractorCommand> = Channel::in_layer(
    Layer::Hardware,
    "hw/tractor/command",
    Qos::STATE,
    "target along the row (or stop) to the tractor pulling the trailer",
);
/// The trailer's position along the row and motion state, latched, 20 Hz.
pub const HW_TRACTOR_FEEDBACK: Channel<TractorFeedback> = Channel::in_layer(
    Layer::Hardware,
    "hw/tractor/feedback",
    Qos::STATE,
    "trailer position along the row and motion state, 20 Hz",
);
/// True apple centres and states from the simulator, latched; for evaluation only (no stack
/// process subscribes).
pub const SIM_GROUND_TRUTH: Channel<GroundTruth> = Channel::in_layer(
    Layer::Evaluation,
    "sim/ground_truth",
    Qos::STATE,
    "true apple centres and states, for evaluation only",
);

/// Integrated LiDAR point clouds (Livox Mid-70), published by the `lidar` process.
pub const LIDAR_POINTS: Channel<PointCloud> = Channel::new(
    "lidar/points",
    Qos::FRAMES,
    "integrated solid-state LiDAR point clouds (<= 100k points, LiDAR frame), 1 Hz by default",
);
/// The simulated (or real) LiDAR device's 10 Hz frames, integrated by the LiDAR driver.
pub const HW_LIDAR_POINTS: Channel<PointCloud> = Channel::in_layer(
    Layer::Hardware,
    "hw/lidar/points",
    Qos {
        max_subscribers: 2,
        subscriber_max_buffer_size: 8,
        max_nodes: 8,
        ..Qos::FRAMES
    },
    "point frames as the LiDAR device delivers them to its driver, 10 Hz",
);

// --- Operator channels: commands, acknowledgements, the mode, manual arm orders.

/// Operator commands to the executive (`harvest ctl`, the console; the safety monitor asks on
/// `safety/violation` instead).
pub const OPERATOR_COMMAND: Channel<OperatorCommand> = Channel::new(
    "operator/command",
    Qos {
        max_publishers: 8,
        max_nodes: 24,
        ..Qos::SMALL
    },
    "operator commands (start, pause, e-stop, jog, ...) with the control token, to the executive",
);
/// The executive's acknowledgement of each operator command.
pub const OPERATOR_ACK: Channel<OperatorAck> = Channel::new(
    "operator/ack",
    Qos {
        max_subscribers: 16,
        max_nodes: 24,
        ..Qos::SMALL
    },
    "each operator command accepted, or refused with a reason",
);
/// The stack's operating mode, as the executive enforces it.
pub const OPERATOR_MODE: Channel<OperatorModeState> = Channel::new(
    "operator/mode",
    Qos {
        max_subscribers: 16,
        max_nodes: 24,
        ..Qos::STATE
    },
    "mode (idle, harvesting, paused, manual, estopped), arms enabled, controlling session, 10 Hz",
);
/// Manual motion orders the executive forwards to each arm.
pub const ARM_MANUAL: [Channel<ArmManualCommand>; 2] = [
    Channel::new(
        "arm1/manual",
        Qos::SMALL,
        "manual motion orders to arm 1 (jog, drop-off), from the executive",
    ),
    Channel::new(
        "arm2/manual",
        Qos::SMALL,
        "manual motion orders to arm 2 (jog, drop-off), from the executive",
    ),
];

/// Operator marks: any operator client may publish one (`harvest ctl mark`, the console); a
/// mark is a note, not a command, so it needs no token. Readers: the recorder (a flight-recorder
/// clip around each mark, the events channel of the recording).
pub const OPERATOR_MARK: Channel<OperatorMark> = Channel::new(
    "operator/mark",
    Qos {
        max_publishers: 8,
        max_nodes: 24,
        ..Qos::SMALL
    },
    "an operator's note that something worth keeping happened now (the recorder files a clip)",
);

/// Called once per catalogue channel with its payload type.
pub trait ChannelVisitor {
    /// Called with one channel of the catalogue.
    fn visit<T: Payload>(&mut self, channel: Channel<T>);
}

/// Visits every channel of the catalogue (recorder, replay, `rec` tools, docs).
pub fn visit_all(visitor: &mut impl ChannelVisitor) {
    visitor.visit(CAMERA_RGBD);
    visitor.visit(PERCEPTION_APPLES);
    visitor.visit(LASER_SCAN_REQUEST);
    visitor.visit(LASER_SCAN_RESULT);
    for arm in ArmId::ALL {
        visitor.visit(ARM_TARGET[arm.index()]);
        visitor.visit(ARM_COMMAND[arm.index()]);
        visitor.visit(ARM_STATE[arm.index()]);
    }
    visitor.visit(VALVE_REQUEST);
    visitor.visit(VALVE_GRANT);
    visitor.visit(VACUUM_STATE);
    visitor.visit(EMERGENCY_STOP);
    visitor.visit(SAFETY_VIOLATION);
    visitor.visit(HARVEST_EVENTS);
    visitor.visit(PROCESS_HEALTH);
    visitor.visit(HW_CAMERA_RGBD);
    for arm in ArmId::ALL {
        visitor.visit(HW_ARM_SERVO[arm.index()]);
        visitor.visit(HW_ARM_ENCODERS[arm.index()]);
    }
    visitor.visit(HW_VALVE_COMMAND);
    visitor.visit(HW_VALVE_READINGS);
    visitor.visit(HW_ALACS_COMMAND);
    visitor.visit(HW_ALACS_IMAGE);
    visitor.visit(HW_PLATFORM_COMMAND);
    visitor.visit(HW_PLATFORM_FEEDBACK);
    visitor.visit(HW_TRACTOR_COMMAND);
    visitor.visit(HW_TRACTOR_FEEDBACK);
    visitor.visit(SIM_GROUND_TRUTH);
    visitor.visit(LIDAR_POINTS);
    visitor.visit(HW_LIDAR_POINTS);
    visitor.visit(OPERATOR_COMMAND);
    visitor.visit(OPERATOR_ACK);
    visitor.visit(OPERATOR_MODE);
    visitor.visit(OPERATOR_MARK);
    for arm in ArmId::ALL {
        visitor.visit(ARM_MANUAL[arm.index()]);
    }
    // Last: the recorder opens its taps in this order, so once it hears a node's tick records
    // it already hears every channel the node reads and writes (`harvest replay --check`
    // compares a tick's outputs only from then on).
    for arm in ArmId::ALL {
        visitor.visit(ARM_TICKS[arm.index()]);
    }
    visitor.visit(VACUUM_TICKS);
}

/// Every channel's spec, in catalogue order.
pub fn all_specs() -> Vec<ChannelSpec> {
    struct Collect(Vec<ChannelSpec>);
    impl ChannelVisitor for Collect {
        fn visit<T: Payload>(&mut self, channel: Channel<T>) {
            self.0.push(channel.spec);
        }
    }
    let mut collect = Collect(Vec::new());
    visit_all(&mut collect);
    collect.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_channel_serves_eight_readers_in_the_memory_four_had() {
        let frames = CAMERA_RGBD.spec.qos;
        assert!(
            frames.max_subscribers >= 8,
            "the stack's 4 readers + 4 tools"
        );
        // Before: 4 subscribers x (buffer 8 + 2 borrowed) + 0 history + 2 loans.
        let before = 4 * (8 + SUBSCRIBER_MAX_BORROWED_SAMPLES) + 2;
        assert_eq!(before, 42);
        assert!(frames.data_segment_samples() <= before);
        assert!(frames.max_nodes > frames.max_subscribers);
        // The hardware-layer frame channels keep their sizing (driver + one observer).
        for qos in [
            HW_CAMERA_RGBD.spec.qos,
            HW_ALACS_IMAGE.spec.qos,
            HW_LIDAR_POINTS.spec.qos,
        ] {
            assert_eq!(qos.data_segment_samples(), 2 * (8 + 2) + 2);
        }
    }

    #[test]
    fn topics_are_unique_and_well_formed() {
        let specs = all_specs();
        let mut topics: Vec<_> = specs.iter().map(|s| s.topic).collect();
        topics.sort_unstable();
        topics.dedup();
        assert_eq!(topics.len(), specs.len());
        for spec in &specs {
            assert!(
                spec.topic.bytes().all(|b| b.is_ascii_lowercase()
                    || b.is_ascii_digit()
                    || b == b'/'
                    || b == b'_')
            );
            assert!(spec.qos.default_buffer_size <= spec.qos.subscriber_max_buffer_size);
        }
    }

    #[test]
    fn only_channels_with_several_writers_accept_several_publishers() {
        let several: Vec<(&str, usize)> = all_specs()
            .iter()
            .filter(|spec| !spec.qos.single_writer())
            .map(|spec| (spec.topic, spec.qos.max_publishers))
            .collect();
        assert_eq!(
            several,
            [
                ("vacuum/valve_request", 2),
                ("harvest/events", 6),
                ("system/health", 24),
                // Operator clients (console, ctl sessions): the executive decides which one
                // controls.
                ("operator/command", 8),
                // Marks are notes from any operator client.
                ("operator/mark", 8)
            ]
        );
    }

    #[test]
    fn ad_hoc_channels_stay_out_of_the_catalogue() {
        let channel = Channel::<LaserScanRequest>::ad_hoc("bench/test", Qos::SMALL);
        assert_eq!(channel.spec.layer, Layer::Evaluation);
        assert_eq!(channel.spec.service_name(), "harvest/bench/test");
        assert_eq!(channel.spec.type_name, LaserScanRequest::TYPE_NAME);
        assert!(all_specs().iter().all(|spec| spec.topic != "bench/test"));
    }
}
