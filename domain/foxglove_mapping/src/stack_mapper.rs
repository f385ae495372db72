//! The mapping of every stack channel but the camera frames ([`crate::camera`], encoded on a
//! thread of its own by the live bridge): the state it needs across messages (apple states, arm
//! phases for the model's colours) and which topics each channel writes.

use crate::arm_frames::{arm_joints, arm_transforms};
use crate::camera::ImageSettings;
use crate::detections::{annotations, detected_apples};
use crate::error::MapError;
use crate::events::{emergency_stop_log, event_log};
use crate::frames;
use crate::geometry::frame_transform;
use crate::harvest_apples::HarvestApples;
use crate::point_clouds::{laser_scan, lidar_cloud};
use crate::robot_scene::robot_model;
use crate::stamps::TimeBase;
use crate::topics::{self, MappedSink};
use crate::vacuum::vacuum_view;
use foxglove::messages::FrameTransforms;
use harvest_ipc::ArmId;
use harvest_ipc::camera_model::RigidTransform;
use harvest_ipc::payloads::{
    AppleDetections, ArmPhase, ArmState, EmergencyStop, HarvestEvent, LaserScanResult, PointCloud,
    VacuumState,
};

/// The robot model is written again at least this often (late joiners, seeking in a
/// recording), ns.
pub const MODEL_PERIOD_NS: u64 = 1_000_000_000;

/// What the mapping needs to know about the robot beyond the messages.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Mounting {
    /// The colour camera's pose in the robot frame (calibration file).
    pub robot_from_camera: Option<RigidTransform>,
    /// The LiDAR's pose in the colour camera frame (extrinsic file).
    pub camera_from_lidar: Option<RigidTransform>,
}

/// Maps stack messages (not camera frames) to their topics.
#[derive(Debug)]
pub struct StackMapper {
    time: TimeBase,
    image: ImageSettings,
    mounting: Mounting,
    apples: HarvestApples,
    phases: [Option<ArmPhase>; 2],
    /// When the model is due again (output time base), `None` before the first.
    model_due_ns: Option<u64>,
}

impl StackMapper {
    /// `image` must be the settings the camera images are shown with (annotations are drawn in
    /// the shown image's pixels).
    pub fn new(time: TimeBase, image: ImageSettings, mounting: Mounting) -> Self {
        Self {
            time,
            image,
            mounting,
            apples: HarvestApples::new(),
            phases: [None; 2],
            model_due_ns: None,
        }
    }

    pub fn time(&self) -> TimeBase {
        self.time
    }

    /// `perception/apples`: the image overlay and the detected spheres.
    pub fn detections<S: MappedSink>(
        &mut self,
        detections: &AppleDetections,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        let log_time_ns = self.time.ns(log_time_ns);
        sink.write(
            topics::CAMERA_ANNOTATIONS,
            log_time_ns,
            &annotations(detections, &self.image, &self.time),
        )
        .map_err(MapError::Sink)?;
        sink.write(
            topics::DETECTED_APPLES,
            log_time_ns,
            &detected_apples(detections, &self.time),
        )
        .map_err(MapError::Sink)
    }

    /// `armN/state`: the chain transforms and joints; the robot model when the arm's phase
    /// changed or [`MODEL_PERIOD_NS`] passed.
    pub fn arm_state<S: MappedSink>(
        &mut self,
        arm: ArmId,
        state: &ArmState,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        let log_time_ns = self.time.ns(log_time_ns);
        sink.write(
            topics::TRANSFORMS,
            log_time_ns,
            &arm_transforms(arm, state, &self.time),
        )
        .map_err(MapError::Sink)?;
        sink.write(
            topics::ARM_JOINTS[arm.index()],
            log_time_ns,
            &arm_joints(state, &self.time),
        )
        .map_err(MapError::Sink)?;
        let phase = state.phase.get().ok();
        let changed = self.phases[arm.index()] != phase;
        self.phases[arm.index()] = phase;
        if changed || self.model_due_ns.is_none_or(|due| log_time_ns >= due) {
            self.model_due_ns = Some(log_time_ns.saturating_add(MODEL_PERIOD_NS));
            let timestamp = self.time.timestamp(state.header.capture_ns);
            sink.write(
                topics::ROBOT_MODEL,
                log_time_ns,
                &robot_model(self.phases, timestamp),
            )
            .map_err(MapError::Sink)?;
            // The camera mounting too, so the camera frames hang on the robot before (and
            // without) camera images.
            if let Some(robot_from_camera) = &self.mounting.robot_from_camera {
                let transform = frame_transform(
                    timestamp,
                    frames::ROBOT,
                    frames::CAMERA_COLOR,
                    robot_from_camera,
                );
                sink.write(
                    topics::TRANSFORMS,
                    log_time_ns,
                    &FrameTransforms {
                        transforms: vec![transform],
                    },
                )
                .map_err(MapError::Sink)?;
            }
        }
        Ok(())
    }

    /// `vacuum/state`: the plottable view.
    pub fn vacuum<S: MappedSink>(
        &mut self,
        state: &VacuumState,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        sink.write(
            topics::VACUUM,
            self.time.ns(log_time_ns),
            &vacuum_view(state, &self.time),
        )
        .map_err(MapError::Sink)
    }

    /// `harvest/events`: a log line, and the apple's sphere when its state changed.
    pub fn event<S: MappedSink>(
        &mut self,
        event: &HarvestEvent,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        let log_time_ns = self.time.ns(log_time_ns);
        sink.write(topics::EVENTS, log_time_ns, &event_log(event, &self.time))
            .map_err(MapError::Sink)?;
        if let Some(update) = self.apples.update(event, &self.time) {
            sink.write(topics::HARVEST_APPLES, log_time_ns, &update)
                .map_err(MapError::Sink)?;
        }
        Ok(())
    }

    /// `safety/emergency_stop`: a log line.
    pub fn emergency_stop<S: MappedSink>(
        &mut self,
        stop: &EmergencyStop,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        sink.write(
            topics::EVENTS,
            self.time.ns(log_time_ns),
            &emergency_stop_log(stop, &self.time),
        )
        .map_err(MapError::Sink)
    }

    /// `lidar/points`: the cloud, and the LiDAR's mounting when known.
    pub fn lidar<S: MappedSink>(
        &mut self,
        cloud: &PointCloud,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        let log_time_ns = self.time.ns(log_time_ns);
        if let Some(camera_from_lidar) = &self.mounting.camera_from_lidar {
            let transform = frame_transform(
                self.time.timestamp(cloud.header.capture_ns),
                frames::CAMERA_COLOR,
                frames::LIDAR,
                camera_from_lidar,
            );
            sink.write(
                topics::TRANSFORMS,
                log_time_ns,
                &FrameTransforms {
                    transforms: vec![transform],
                },
            )
            .map_err(MapError::Sink)?;
        }
        sink.write(
            topics::LIDAR_CLOUD,
            log_time_ns,
            &lidar_cloud(cloud, &self.time),
        )
        .map_err(MapError::Sink)
    }

    /// `laser/scan_result`: the candidates and the final position.
    pub fn laser_scan<S: MappedSink>(
        &mut self,
        result: &LaserScanResult,
        log_time_ns: u64,
        sink: &mut S,
    ) -> Result<(), MapError<S::Error>> {
        sink.write(
            topics::LASER_SCAN,
            self.time.ns(log_time_ns),
            &laser_scan(result, &self.time),
        )
        .map_err(MapError::Sink)
    }
}
