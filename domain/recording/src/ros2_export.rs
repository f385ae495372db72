//! `harvest rec export FILE --ros2 OUT`: a recording as a rosbag2 bag (MCAP storage, CDR) with
//! standard message types that ROS 2 tools and the Python `rosbags` package read: the camera
//! frames as colour and depth `Image` with their `CameraInfo`, the detections as
//! `vision_msgs/Detection3DArray`, the arms' joints as `JointState`, the LiDAR clouds as
//! `PointCloud2` (topics and frames: `harvest_ros2_mapping`).
//!
//! A continuous record holds the camera as H.264 video (`camera/video`) and depth images at a
//! reduced rate (`camera/depth`) instead of raw frames ([`crate::camera_record`]): the export
//! decodes the video back into frames and writes the same topics, the colour image for every
//! video frame and the depth image when the recording has that frame's depth (video frames
//! before the first depth image or the first key frame have no frame and are counted as
//! skipped).
//!
//! Time: a message's `header.stamp` is its payload's time of validity (`capture_ns`; the
//! source frame's for detections) and its bag receive time is the recording's log time, both
//! on the recording's UTC time base (`harvest.clock`), as ROS 2 stamps are system time. A
//! recording without a clock record keeps its stack-clock stamps.

use crate::camera_record::{
    CameraRebuild, DEPTH_SCHEMA, DEPTH_TOPIC, Rebuilt, VIDEO_TOPIC, video_channel,
};
use crate::recording_file::ReadError;
use crate::scan::{ScanEnd, ScanItem, ScanOptions, scan_file};
use crate::schema::schema_name;
use crate::time_base::FileTimeBase;
use crate::time_window::{absolute_window, recording_start_ns};
use crate::topic_filter::TopicFilter;
use harvest_ipc::Payload;
use harvest_ipc::catalogue::{ARM_STATE, CAMERA_RGBD, LIDAR_POINTS, PERCEPTION_APPLES};
use harvest_ipc::payloads::{AppleDetections, ArmState, PointCloud, RgbdFrame};
use harvest_ros2::msgs::sensor_msgs::{
    CAMERA_INFO_TYPE, IMAGE_TYPE, JOINT_STATE_TYPE, POINT_CLOUD2_TYPE,
};
use harvest_ros2::msgs::vision_msgs::DETECTION_3D_ARRAY_TYPE;
use harvest_ros2::rosbag2::{BagWriter, QosProfile, TopicId};
use harvest_ros2::{MessageType, RosMessage};
use harvest_ros2_mapping::to_ros;
use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::Path;
use std::time::Duration;

/// What the ROS 2 export wrote.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Ros2ExportReport {
    /// ROS 2 topic -> messages written.
    pub written: BTreeMap<String, u64>,
    /// Recorded topic -> (messages not exported, why).
    pub skipped: BTreeMap<String, (u64, String)>,
    /// Why the input could not be read to its end, if so.
    pub incomplete: Option<String>,
}

impl Ros2ExportReport {
    pub fn messages(&self) -> u64 {
        self.written.values().sum()
    }
}

/// How one recorded channel is exported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mapping {
    Camera,
    /// `camera/video`: H.264 colour images, decoded with the latest `camera/depth`.
    Video,
    /// `camera/depth`: depth images with the frames' metadata.
    Depth,
    Detections,
    Joints,
    Points,
}

impl Mapping {
    /// The mapping of a recorded channel, by topic and schema (this build's payload version).
    fn of(topic: &str, schema: &str) -> Result<Self, String> {
        let candidates: [(&str, String, Mapping); 7] = [
            (VIDEO_TOPIC, video_channel().schema_name, Mapping::Video),
            (DEPTH_TOPIC, DEPTH_SCHEMA.to_owned(), Mapping::Depth),
            (
                CAMERA_RGBD.spec.topic,
                schema_name(RgbdFrame::TYPE_NAME, RgbdFrame::VERSION),
                Mapping::Camera,
            ),
            (
                PERCEPTION_APPLES.spec.topic,
                schema_name(AppleDetections::TYPE_NAME, AppleDetections::VERSION),
                Mapping::Detections,
            ),
            (
                ARM_STATE[0].spec.topic,
                schema_name(ArmState::TYPE_NAME, ArmState::VERSION),
                Mapping::Joints,
            ),
            (
                ARM_STATE[1].spec.topic,
                schema_name(ArmState::TYPE_NAME, ArmState::VERSION),
                Mapping::Joints,
            ),
            (
                LIDAR_POINTS.spec.topic,
                schema_name(PointCloud::TYPE_NAME, PointCloud::VERSION),
                Mapping::Points,
            ),
        ];
        match candidates.iter().find(|(name, _, _)| *name == topic) {
            Some((_, expected, mapping)) if expected == schema => Ok(*mapping),
            Some((_, expected, _)) => Err(format!(
                "recorded as {schema:?}, this build maps {expected}"
            )),
            None => Err("no standard ROS 2 message type is mapped for this channel".to_owned()),
        }
    }
}

/// Writes the bag and its topics as they are first needed.
struct Ros2Output {
    bag: BagWriter,
    topics: BTreeMap<String, TopicId>,
    report: Ros2ExportReport,
}

impl Ros2Output {
    fn write(
        &mut self,
        topic: &str,
        ty: &'static MessageType,
        qos: QosProfile,
        log_time_ns: u64,
        message: &impl RosMessage,
    ) -> Result<(), String> {
        let id = match self.topics.get(topic) {
            Some(id) => *id,
            None => {
                let id = self
                    .bag
                    .add_topic(topic, ty, qos)
                    .map_err(|error| error.to_string())?;
                self.topics.insert(topic.to_owned(), id);
                id
            }
        };
        self.bag
            .write(id, log_time_ns, &message.to_cdr())
            .map_err(|error| error.to_string())?;
        *self.report.written.entry(topic.to_owned()).or_insert(0) += 1;
        Ok(())
    }

    /// The four camera topics of one frame stamped `stamp_ns`; the depth pair only `with_depth`.
    fn write_camera(
        &mut self,
        frame: &RgbdFrame,
        stamp_ns: u64,
        log_ns: u64,
        with_depth: bool,
    ) -> Result<(), String> {
        let messages = to_ros::camera_messages(frame, stamp_ns);
        let qos = QosProfile::SENSOR_DATA;
        self.write(
            to_ros::COLOR_IMAGE_TOPIC,
            &IMAGE_TYPE,
            qos,
            log_ns,
            &messages.color,
        )?;
        self.write(
            to_ros::COLOR_INFO_TOPIC,
            &CAMERA_INFO_TYPE,
            qos,
            log_ns,
            &messages.color_info,
        )?;
        if !with_depth {
            return Ok(());
        }
        self.write(
            to_ros::DEPTH_IMAGE_TOPIC,
            &IMAGE_TYPE,
            qos,
            log_ns,
            &messages.depth,
        )?;
        self.write(
            to_ros::DEPTH_INFO_TOPIC,
            &CAMERA_INFO_TYPE,
            qos,
            log_ns,
            &messages.depth_info,
        )
    }

    /// Counts a recorded message that gave nothing to export, and why.
    fn skip(&mut self, topic: &str, reason: &str) {
        let entry = self
            .report
            .skipped
            .entry(topic.to_owned())
            .or_insert_with(|| (0, reason.to_owned()));
        entry.0 += 1;
    }
}

/// A decode scratch value per payload type (frames and clouds are megabytes: on the heap).
struct Scratch {
    frame: Box<RgbdFrame>,
    cloud: Box<PointCloud>,
    detections: Box<AppleDetections>,
    arm: Box<ArmState>,
}

/// The video decoder and the latest depth image of a continuous record, made when first needed.
fn camera_rebuild(slot: &mut Option<CameraRebuild>) -> Result<&mut CameraRebuild, String> {
    if slot.is_none() {
        *slot = Some(CameraRebuild::new().map_err(|error| error.to_string())?);
    }
    slot.as_mut().ok_or_else(|| "no video decoder".to_owned())
}

/// Exports `path` (messages of topics matching `topics`, in the window `start`..`end` after the
/// first message) as the bag directory `out`.
pub fn export_ros2(
    path: &Path,
    out: &Path,
    topics: &[String],
    start: Option<Duration>,
    end: Option<Duration>,
) -> Result<Ros2ExportReport, Ros2ExportError> {
    let filter = TopicFilter::patterns(topics, &[]);
    let start_ns = recording_start_ns(path)?.unwrap_or(0);
    let (from_ns, to_ns) = absolute_window(start_ns, start, end);
    let library = format!("harvest {}", crate::metadata::SOFTWARE_VERSION);
    let mut bag =
        BagWriter::create(out, &library).map_err(|e| Ros2ExportError::Output(e.to_string()))?;
    bag.add_custom_data("harvest.source", &path.display().to_string());
    let mut output = Ros2Output {
        bag,
        topics: BTreeMap::new(),
        report: Ros2ExportReport::default(),
    };
    let mut time = FileTimeBase::default();
    let mut mappings: BTreeMap<u16, Result<Mapping, ()>> = BTreeMap::new();
    let mut scratch = Scratch {
        frame: harvest_ipc::payload::boxed_zeroed(),
        cloud: harvest_ipc::payload::boxed_zeroed(),
        detections: harvest_ipc::payload::boxed_zeroed(),
        arm: harvest_ipc::payload::boxed_zeroed(),
    };
    let mut rebuild: Option<CameraRebuild> = None;
    // A depth image came since the last video frame.
    let mut depth_fresh = false;
    let mut failure: Option<String> = None;
    let outcome = scan_file(
        path,
        ScanOptions {
            log_time_window: Some((from_ns, to_ns)),
        },
        |item| {
            let message = match item {
                ScanItem::Metadata(record) => {
                    time.observe(record);
                    return ControlFlow::Continue(());
                }
                ScanItem::Message(message) => message,
                ScanItem::Chunk(_) | ScanItem::DamagedChunk(_) => return ControlFlow::Continue(()),
            };
            let channel = &message.channel;
            if message.log_time < from_ns
                || message.log_time > to_ns
                || !filter.matches_topic(&channel.topic)
            {
                return ControlFlow::Continue(());
            }
            let mapping = mappings.entry(channel.id).or_insert_with(|| {
                let schema = channel
                    .schema
                    .as_ref()
                    .map(|s| s.name.as_str())
                    .unwrap_or("");
                Mapping::of(&channel.topic, schema).map_err(|reason| {
                    output
                        .report
                        .skipped
                        .insert(channel.topic.clone(), (0, reason));
                })
            });
            let Ok(mapping) = *mapping else {
                if let Some((count, _)) = output.report.skipped.get_mut(&channel.topic) {
                    *count += 1;
                }
                return ControlFlow::Continue(());
            };
            let log_ns = time
                .realtime_ns(message.log_time)
                .unwrap_or(message.log_time);
            let stamp = |capture_ns: u64| {
                time.realtime_pair()
                    .map(|pair| pair.to_realtime_ns(capture_ns))
                    .unwrap_or(capture_ns)
            };
            let result = match mapping {
                Mapping::Camera => RgbdFrame::decode_into(message.data, &mut scratch.frame)
                    .map_err(|e| e.to_string())
                    .and_then(|()| {
                        let stamp_ns = stamp(scratch.frame.header.capture_ns);
                        output.write_camera(&scratch.frame, stamp_ns, log_ns, true)
                    }),
                Mapping::Depth => camera_rebuild(&mut rebuild).and_then(|rebuild| {
                    rebuild.depth(message.data).map_err(|e| e.to_string())?;
                    depth_fresh = true;
                    Ok(())
                }),
                Mapping::Video => camera_rebuild(&mut rebuild).and_then(|rebuild| {
                    // The video's timestamps are on the file's UTC base already.
                    let rebuilt = rebuild
                        .video(message.data, |utc_ns| utc_ns, &mut scratch.frame)
                        .map_err(|e| e.to_string())?;
                    if rebuilt != Rebuilt::Frame {
                        output.skip(
                            &channel.topic,
                            "before the first depth image or key frame: no frame yet",
                        );
                        return Ok(());
                    }
                    let with_depth = std::mem::take(&mut depth_fresh);
                    let stamp_ns = scratch.frame.header.capture_ns;
                    output.write_camera(&scratch.frame, stamp_ns, log_ns, with_depth)
                }),
                Mapping::Detections => {
                    AppleDetections::decode_into(message.data, &mut scratch.detections)
                        .map_err(|e| e.to_string())
                        .and_then(|()| {
                            let array = to_ros::detections(
                                &scratch.detections,
                                stamp(scratch.detections.source_capture_ns),
                            );
                            output.write(
                                to_ros::DETECTIONS_TOPIC,
                                &DETECTION_3D_ARRAY_TYPE,
                                QosProfile::DEFAULT,
                                log_ns,
                                &array,
                            )
                        })
                }
                Mapping::Joints => ArmState::decode_into(message.data, &mut scratch.arm)
                    .map_err(|e| e.to_string())
                    .and_then(|()| {
                        let joints =
                            to_ros::joint_state(&scratch.arm, stamp(scratch.arm.header.capture_ns));
                        let topic = to_ros::joint_states_topic(scratch.arm.arm_id);
                        output.write(
                            &topic,
                            &JOINT_STATE_TYPE,
                            QosProfile::DEFAULT,
                            log_ns,
                            &joints,
                        )
                    }),
                Mapping::Points => PointCloud::decode_into(message.data, &mut scratch.cloud)
                    .map_err(|e| e.to_string())
                    .and_then(|()| {
                        let cloud = to_ros::point_cloud(
                            &scratch.cloud,
                            stamp(scratch.cloud.header.capture_ns),
                        );
                        output.write(
                            to_ros::POINTS_TOPIC,
                            &POINT_CLOUD2_TYPE,
                            QosProfile::SENSOR_DATA,
                            log_ns,
                            &cloud,
                        )
                    }),
            };
            match result {
                Ok(()) => ControlFlow::Continue(()),
                Err(error) => {
                    failure = Some(format!("{}: {error}", channel.topic));
                    ControlFlow::Break(())
                }
            }
        },
    )?;
    if let Some(error) = failure {
        return Err(Ros2ExportError::Output(error));
    }
    let Ros2Output {
        bag, mut report, ..
    } = output;
    bag.finish()
        .map_err(|error| Ros2ExportError::Output(error.to_string()))?;
    if let ScanEnd::Truncated { reason, .. } = outcome.end {
        report.incomplete = Some(reason);
    }
    Ok(report)
}

/// The ROS 2 export failed.
#[derive(Debug, thiserror::Error)]
pub enum Ros2ExportError {
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Writing the bag failed, or a recorded message could not be decoded.
    #[error("ROS 2 export: {0}")]
    Output(String),
}
