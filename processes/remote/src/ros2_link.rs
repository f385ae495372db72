//! `harvest remote --ros2-domain N`: the robot as a ROS 2 node over rmw_zenoh, on the link's
//! own session (a Jazzy machine running `rmw_zenohd`, which the link connects to, sees it with
//! `ros2 node list` / `ros2 topic echo`; key expressions, tokens and attachments in
//! `harvest_remote::ros2_graph`):
//!
//! - `/<robot>/arm<N>/joint_states` (`sensor_msgs/msg/JointState`) at the link's arm-state rate;
//! - `/<robot>/perception/apples` (`vision_msgs/msg/Detection3DArray`, the type rosbag export
//!   writes: the centre as the pose, the apple's bounding cube, `apple` and the confidence as the
//!   hypothesis, the track id as `id`) at the link's detections rate;
//! - `/<robot>/harvest/events` (`std_msgs/msg/String`, each event's JSON line, as the link's
//!   own events key carries it: ROS has no standard type for a pick cycle's events);
//! - `/<robot>/camera/color/image_raw/compressed` (`sensor_msgs/msg/CompressedImage`, format
//!   `jpeg`): the link's downscaled JPEG, sent by the camera thread at its pace only while a ROS
//!   subscriber (or a station) matches ([`RosCamera`]);
//! - `/<robot>/diagnostics` (`diagnostic_msgs/msg/DiagnosticArray`, one status per process
//!   heartbeat heard: OK starting or running, WARN degraded or stopping, ERROR failed);
//! - in: `/<robot>/emergency_stop` (`std_msgs/msg/Bool`): `true` engages the emergency stop as
//!   the console's button does (a stop needs no authority); `false` is ignored (a stop is never
//!   released implicitly, and never from ROS).
//!
//! Stamps in the messages' headers are the stack's capture stamps on the wall clock (ROS
//! time); the attachment's source timestamp is the wall clock at the put.

use std::time::{SystemTime, UNIX_EPOCH};

use harvest_ipc::operator_client::OperatorClient;
use harvest_ipc::payloads::{
    AppleDetections, ArmState, HarvestEvent, ProcessHealth, ProcessRunState,
};
use harvest_ipc::{Domain, MonotonicClock};
use harvest_operator::Command;
use harvest_remote::RobotName;
use harvest_remote::remote_request::forwarded_session;
use harvest_remote::ros2_graph::{Endpoint, Ros2Node, Ros2Topic, attachment, gid};
use harvest_remote::state_encoding::json_bytes;
use harvest_ros2::RosMessage;
use harvest_ros2::msgs::diagnostic_msgs::{
    DIAGNOSTIC_ARRAY_TYPE, DiagnosticArray, DiagnosticStatus, KeyValue,
};
use harvest_ros2::msgs::sensor_msgs::{COMPRESSED_IMAGE_TYPE, CompressedImage, JOINT_STATE_TYPE};
use harvest_ros2::msgs::std_msgs::{BOOL_TYPE, Bool, Header, STRING_TYPE, StringMessage};
use harvest_ros2::msgs::vision_msgs::DETECTION_3D_ARRAY_TYPE;
use harvest_ros2_mapping::frames::COLOR_OPTICAL_FRAME;
use harvest_ros2_mapping::to_ros;
use tracing::{debug, info, warn};
use zenoh::Wait;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;

use crate::command_lane::spawn_with_client;
use crate::error::RemoteError;

/// How long the ROS e-stop waits for the executive's answer before it logs none came.
const ESTOP_ACK_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(1500);

/// Nanoseconds since the epoch, now.
fn wall_now_ns() -> i64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |since| {
            i64::try_from(since.as_nanos()).unwrap_or(i64::MAX)
        })
}

/// A stack-clock stamp on the wall clock (ROS time), by the clocks' offset now.
fn ros_stamp_ns(stack_ns: u64) -> u64 {
    let age_ns = MonotonicClock::read_ns().saturating_sub(stack_ns);
    u64::try_from(wall_now_ns())
        .unwrap_or(0)
        .saturating_sub(age_ns)
}

/// One ROS 2 publisher: its Zenoh publisher, liveliness token, GID and sequence.
struct RosPublisher {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    sequence: i64,
    failed: u64,
}

impl RosPublisher {
    fn declare(
        session: &zenoh::Session,
        node: &Ros2Node,
        topic: &Ros2Topic,
        entity_id: u32,
    ) -> Result<Self, RemoteError> {
        let token_key = node.endpoint_token(topic, Endpoint::Publisher, entity_id);
        let token = session
            .liveliness()
            .declare_token(token_key.clone())
            .wait()?;
        let publisher = session
            .declare_publisher(topic.key.clone())
            .congestion_control(CongestionControl::Drop)
            .wait()?;
        Ok(Self {
            publisher,
            _token: token,
            gid: gid(&token_key),
            sequence: 0,
            failed: 0,
        })
    }

    /// Puts `message` (CDR) with its attachment; a failed put is counted, never fatal.
    fn put<M: RosMessage>(&mut self, message: &M) {
        self.sequence += 1;
        let attachment = attachment(self.sequence, wall_now_ns(), &self.gid);
        if let Err(error) = self
            .publisher
            .put(message.to_cdr())
            .attachment(attachment.to_vec())
            .wait()
        {
            self.failed += 1;
            debug!(%error, key = %self.publisher.key_expr(), "ROS 2 put failed");
        }
    }
}

/// The camera's ROS 2 publisher, handed to the camera thread.
pub struct RosCamera {
    publisher: RosPublisher,
}

impl RosCamera {
    /// The Zenoh publisher, for its matching listener.
    pub fn publisher(&self) -> &Publisher<'static> {
        &self.publisher.publisher
    }

    /// Puts one JPEG of the frame captured at `capture_ns` (stack clock).
    pub fn put(&mut self, jpeg: &[u8], capture_ns: u64) {
        self.publisher.put(&CompressedImage {
            header: Header::new(ros_stamp_ns(capture_ns), COLOR_OPTICAL_FRAME),
            format: "jpeg".to_owned(),
            data: jpeg.to_vec(),
        });
    }
}

/// The robot's ROS 2 node on the link (module documentation).
pub struct Ros2Link {
    _node_token: LivelinessToken,
    _estop_token: LivelinessToken,
    joint_states: [RosPublisher; 2],
    detections: RosPublisher,
    events: RosPublisher,
    diagnostics: RosPublisher,
    camera: Option<RosCamera>,
}

impl Ros2Link {
    /// Declares the node, its publishers and the e-stop subscription (whose thread sends the
    /// stop to the executive through its own `operator/command` publisher).
    pub fn declare(
        session: &zenoh::Session,
        robot: &RobotName,
        ros_domain_id: u32,
        domain: &Domain,
        process_name: &str,
    ) -> Result<Self, RemoteError> {
        let node = Ros2Node::new(ros_domain_id, &session.zid().to_string(), robot);
        let node_token = session
            .liveliness()
            .declare_token(node.node_token())
            .wait()?;
        let joint_states = [
            RosPublisher::declare(
                session,
                &node,
                &node.topic("arm1/joint_states", &JOINT_STATE_TYPE),
                1,
            )?,
            RosPublisher::declare(
                session,
                &node,
                &node.topic("arm2/joint_states", &JOINT_STATE_TYPE),
                2,
            )?,
        ];
        let detections = RosPublisher::declare(
            session,
            &node,
            &node.topic("perception/apples", &DETECTION_3D_ARRAY_TYPE),
            3,
        )?;
        let events = RosPublisher::declare(
            session,
            &node,
            &node.topic("harvest/events", &STRING_TYPE),
            4,
        )?;
        let diagnostics = RosPublisher::declare(
            session,
            &node,
            &node.topic("diagnostics", &DIAGNOSTIC_ARRAY_TYPE),
            5,
        )?;
        let camera = RosCamera {
            publisher: RosPublisher::declare(
                session,
                &node,
                &node.topic("camera/color/image_raw/compressed", &COMPRESSED_IMAGE_TYPE),
                7,
            )?,
        };
        let estop_topic = node.topic("emergency_stop", &BOOL_TYPE);
        let estop_token = session
            .liveliness()
            .declare_token(node.endpoint_token(&estop_topic, Endpoint::Subscription, 6))
            .wait()?;
        spawn_estop(session, &estop_topic, domain, process_name)?;
        info!(
            namespace = node.namespace(),
            ros_domain_id, "ROS 2 node on the link (rmw_zenoh)"
        );
        Ok(Self {
            _node_token: node_token,
            _estop_token: estop_token,
            joint_states,
            detections,
            events,
            diagnostics,
            camera: Some(camera),
        })
    }

    /// The camera's publisher, for the camera thread (once).
    pub fn take_camera(&mut self) -> Option<RosCamera> {
        self.camera.take()
    }

    pub fn arm_state(&mut self, state: &ArmState) {
        let index = usize::from(state.arm_id.saturating_sub(1));
        if let Some(publisher) = self.joint_states.get_mut(index) {
            publisher.put(&to_ros::joint_state(
                state,
                ros_stamp_ns(state.header.capture_ns),
            ));
        }
    }

    pub fn detections(&mut self, detections: &AppleDetections) {
        self.detections.put(&to_ros::detections(
            detections,
            ros_stamp_ns(detections.header.capture_ns),
        ));
    }

    pub fn event(&mut self, event: &HarvestEvent) {
        let data = String::from_utf8_lossy(&json_bytes(event)).into_owned();
        self.events.put(&StringMessage { data });
    }

    pub fn health(&mut self, beat: &ProcessHealth) {
        let (level, state) = match beat.run_state.get() {
            Ok(ProcessRunState::Starting) => (DiagnosticStatus::OK, "starting"),
            Ok(ProcessRunState::Running) => (DiagnosticStatus::OK, "running"),
            Ok(ProcessRunState::Degraded) => (DiagnosticStatus::WARN, "degraded"),
            Ok(ProcessRunState::Stopping) => (DiagnosticStatus::WARN, "stopping"),
            Ok(ProcessRunState::Failed) => (DiagnosticStatus::ERROR, "failed"),
            Err(_) => (DiagnosticStatus::STALE, "unknown state"),
        };
        let name = beat.process_name.as_str().to_owned();
        let status = DiagnosticStatus {
            level,
            name: format!("harvest/{name}"),
            message: state.to_owned(),
            hardware_id: String::new(),
            values: vec![
                KeyValue {
                    key: "pid".to_owned(),
                    value: beat.pid.to_string(),
                },
                KeyValue {
                    key: beat.detail.as_str().to_owned(),
                    value: beat.detail_value.to_string(),
                },
                KeyValue {
                    key: "deadline_misses".to_owned(),
                    value: beat.deadline_misses.to_string(),
                },
            ],
        };
        self.diagnostics.put(&DiagnosticArray {
            header: Header::new(ros_stamp_ns(beat.header.capture_ns), ""),
            status: vec![status],
        });
    }

    /// Puts that failed (the link down, a full queue).
    pub fn failed_puts(&self) -> u64 {
        self.joint_states.iter().map(|p| p.failed).sum::<u64>()
            + self.detections.failed
            + self.events.failed
            + self.diagnostics.failed
    }
}

/// The e-stop subscription's thread: a `true` from ROS engages the stop through the executive.
fn spawn_estop(
    session: &zenoh::Session,
    topic: &Ros2Topic,
    domain: &Domain,
    process_name: &str,
) -> Result<(), RemoteError> {
    let subscriber = session.declare_subscriber(topic.key_any_hash()).wait()?;
    let key = topic.key.clone();
    spawn_with_client(
        format!("{process_name}-ros2-estop"),
        domain.clone(),
        move |client| {
            info!(%key, "ROS 2 e-stop subscription ready");
            while let Ok(sample) = subscriber.recv() {
                let bytes = sample.payload().to_bytes();
                match Bool::from_cdr(&bytes) {
                    Ok(Bool { data: true }) => send_stop(client),
                    Ok(Bool { data: false }) => {
                        debug!("ROS 2 e-stop false: ignored (a stop is never released from ROS)");
                    }
                    Err(error) => {
                        warn!(%error, key = %sample.key_expr(), "ROS 2 e-stop message refused")
                    }
                }
            }
            warn!("ROS 2 e-stop subscription ended");
        },
    )
}

/// Sends the emergency stop to the executive. A failure is logged and the subscription goes
/// on: the next stop from ROS must still be heard.
fn send_stop(client: &mut OperatorClient) {
    let session = forwarded_session(0);
    let message = Command::EmergencyStop.to_message(0, session, "", "ros2");
    let answer = client
        .send(message)
        .and_then(|request| client.wait_ack(session, request, ESTOP_ACK_TIMEOUT));
    match answer {
        Ok(Some(ack)) => info!(
            accepted = ack.accepted != 0,
            "emergency stop from ROS 2 sent to the executive"
        ),
        Ok(None) => warn!("emergency stop from ROS 2 sent; no answer from the executive"),
        Err(error) => warn!(%error, "emergency stop from ROS 2 not sent"),
    }
}
