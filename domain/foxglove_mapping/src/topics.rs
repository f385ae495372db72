//! The mapped topics: each a Foxglove well-known schema (protobuf) or one of ours
//! ([`crate::vacuum`]), declared once with the stack channel it comes from.
//!
//! Names start with `/` (Foxglove's convention), which also keeps them apart from the raw
//! channels in a recording (`camera/rgbd` raw, `/camera/image` mapped).

use foxglove::Encode;
use foxglove::messages::{
    CameraCalibration, CompressedImage, FrameTransforms, ImageAnnotations, JointStates, Log,
    PointCloud, SceneUpdate,
};
use std::marker::PhantomData;

use crate::vacuum::VacuumView;

/// A mapped topic carrying messages of type `M`.
pub struct Topic<M> {
    /// The Foxglove topic name.
    pub name: &'static str,
    /// The stack channel(s) it is made from, and how.
    pub description: &'static str,
    message: PhantomData<fn() -> M>,
}

impl<M> Clone for Topic<M> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<M> Copy for Topic<M> {}

impl<M> std::fmt::Debug for Topic<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Topic").field("name", &self.name).finish()
    }
}

impl<M: Encode> Topic<M> {
    const fn new(name: &'static str, description: &'static str) -> Self {
        Self {
            name,
            description,
            message: PhantomData,
        }
    }

    /// Name, schema and message encoding of this topic (type-erased).
    pub fn describe(&self) -> TopicDescription {
        TopicDescription {
            name: self.name,
            description: self.description,
            schema: M::get_schema(),
            message_encoding: M::get_message_encoding(),
        }
    }
}

/// A mapped topic's name, schema and message encoding, for writers that register channels
/// themselves (the recorder, the export).
#[derive(Debug, Clone, PartialEq)]
pub struct TopicDescription {
    pub name: &'static str,
    pub description: &'static str,
    /// Name, encoding (`protobuf`) and data (a serialized `FileDescriptorSet`).
    pub schema: Option<foxglove::Schema>,
    /// `protobuf`.
    pub message_encoding: String,
}

pub const CAMERA_IMAGE: Topic<CompressedImage> = Topic::new(
    "/camera/image",
    "camera/rgbd colour image, JPEG, 960x540 by default (live: at the viewing rate; exports: every frame)",
);
pub const CAMERA_CALIBRATION: Topic<CameraCalibration> = Topic::new(
    "/camera/calibration",
    "camera/rgbd colour intrinsics, scaled like /camera/image",
);
pub const CAMERA_ANNOTATIONS: Topic<ImageAnnotations> = Topic::new(
    "/camera/annotations",
    "perception/apples drawn on /camera/image: outline, id, depth source and confidence",
);
pub const DETECTED_APPLES: Topic<SceneUpdate> = Topic::new(
    "/apples/detected",
    "perception/apples as spheres in the robot frame (the newest detection set)",
);
pub const HARVEST_APPLES: Topic<SceneUpdate> = Topic::new(
    "/apples/harvest",
    "harvest/events: the vacuum supervisor's apples coloured by state (assigned, attached, \
harvested, failed, out of reach)",
);
pub const ROBOT_MODEL: Topic<SceneUpdate> = Topic::new(
    "/robot_model",
    "both tube arms (Table 1 geometry, coloured by phase) and the platform, on the arm frames",
);
pub const TRANSFORMS: Topic<FrameTransforms> = Topic::new(
    "/tf",
    "armN/state joints down each arm's chain (eq. 1); the camera and LiDAR mountings",
);
pub const ARM_JOINTS: [Topic<JointStates>; 2] = [
    Topic::new(
        "/arm1/joints",
        "arm1/state joint positions and velocities: d_m, theta_rad, phi_rad, twist_rad",
    ),
    Topic::new(
        "/arm2/joints",
        "arm2/state joint positions and velocities: d_m, theta_rad, phi_rad, twist_rad",
    ),
];
pub const VACUUM: Topic<VacuumView> = Topic::new(
    "/vacuum",
    "vacuum/state as plottable fields: pressures, valves, attachment",
);
pub const LIDAR_CLOUD: Topic<PointCloud> = Topic::new(
    "/lidar/cloud",
    "lidar/points in the lidar frame: x, y, z, intensity",
);
pub const LASER_SCAN: Topic<PointCloud> = Topic::new(
    "/laser/scan",
    "laser/scan_result candidates and final position in the camera_color frame",
);
pub const EVENTS: Topic<Log> = Topic::new(
    "/events",
    "harvest/events and safety/emergency_stop as log lines",
);

/// Every mapped topic, in a stable order.
pub fn all() -> Vec<TopicDescription> {
    vec![
        CAMERA_IMAGE.describe(),
        CAMERA_CALIBRATION.describe(),
        CAMERA_ANNOTATIONS.describe(),
        DETECTED_APPLES.describe(),
        HARVEST_APPLES.describe(),
        ROBOT_MODEL.describe(),
        TRANSFORMS.describe(),
        ARM_JOINTS[0].describe(),
        ARM_JOINTS[1].describe(),
        VACUUM.describe(),
        LIDAR_CLOUD.describe(),
        LASER_SCAN.describe(),
        EVENTS.describe(),
    ]
}

/// Where mapped messages go: a WebSocket channel, a recording, an export.
pub trait MappedSink {
    type Error;
    /// Writes `message` on `topic` at `log_time_ns` (already on the output time base).
    fn write<M: Encode>(
        &mut self,
        topic: Topic<M>,
        log_time_ns: u64,
        message: &M,
    ) -> Result<(), Self::Error>;
}

/// Encodes `message` into `out` (cleared first).
pub fn encode_into<M: Encode>(message: &M, out: &mut Vec<u8>) -> Result<(), M::Error> {
    out.clear();
    if let Some(length) = message.encoded_len() {
        out.reserve(length);
    }
    message.encode(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_are_unique_protobuf_and_apart_from_the_raw_channels() {
        let topics = all();
        let mut names: Vec<&str> = topics.iter().map(|topic| topic.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), topics.len());
        let raw: Vec<&str> = harvest_ipc::catalogue::all_specs()
            .iter()
            .map(|spec| spec.topic)
            .collect();
        for topic in &topics {
            assert!(topic.name.starts_with('/'), "{}", topic.name);
            assert!(!raw.contains(&topic.name));
            assert_eq!(topic.message_encoding, "protobuf");
            let schema = topic.schema.as_ref().expect("schema");
            assert_eq!(schema.encoding, "protobuf");
            assert!(!schema.data.is_empty());
        }
    }
}
