//! Stack payloads as standard ROS 2 messages. Stamps are given by the caller (the bag's time
//! base: Unix-epoch ns for a recording with a clock record); each message's `header.stamp` is
//! the payload's time of validity on that base.

use crate::camera_info::camera_info;
use crate::frames::{COLOR_OPTICAL_FRAME, DEPTH_OPTICAL_FRAME, LIDAR_FRAME, ROBOT_FRAME};
use harvest_ipc::payloads::rgbd_frame::{
    DEPTH_HEIGHT_PX, DEPTH_WIDTH_PX, RGB_HEIGHT_PX, RGB_WIDTH_PX,
};
use harvest_ipc::payloads::{AppleDetections, ArmState, PointCloud, RgbdFrame};
use harvest_ros2::msgs::geometry_msgs::{Point, Pose, PoseWithCovariance, Vector3};
use harvest_ros2::msgs::sensor_msgs::{CameraInfo, Image, JointState, PointCloud2, PointField};
use harvest_ros2::msgs::std_msgs::Header;
use harvest_ros2::msgs::vision_msgs::{
    BoundingBox3D, Detection3D, Detection3DArray, ObjectHypothesis, ObjectHypothesisWithPose,
};

/// Topic of the colour image.
pub const COLOR_IMAGE_TOPIC: &str = "/camera/color/image_raw";
/// Topic of the colour camera's model.
pub const COLOR_INFO_TOPIC: &str = "/camera/color/camera_info";
/// Topic of the depth image (16UC1, millimetres).
pub const DEPTH_IMAGE_TOPIC: &str = "/camera/depth/image_raw";
/// Topic of the depth camera's model.
pub const DEPTH_INFO_TOPIC: &str = "/camera/depth/camera_info";
/// Topic of the detections.
pub const DETECTIONS_TOPIC: &str = "/perception/apples";
/// Topic of the LiDAR clouds.
pub const POINTS_TOPIC: &str = "/lidar/points";
/// The class id of every detection.
pub const APPLE_CLASS: &str = "apple";

/// Topic of one arm's joint states (`/arm1/joint_states`).
pub fn joint_states_topic(arm_id: u8) -> String {
    format!("/arm{arm_id}/joint_states")
}

/// The joints of an arm as ROS names them (`arm1_d`, `arm1_theta`, ...): the prismatic
/// extension D in metres, then the three revolute joints in radians.
pub fn joint_names(arm_id: u8) -> Vec<String> {
    ["d", "theta", "phi", "twist"]
        .iter()
        .map(|joint| format!("arm{arm_id}_{joint}"))
        .collect()
}

/// One RGB-D frame as ROS messages.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraMessages {
    pub color: Image,
    pub color_info: CameraInfo,
    pub depth: Image,
    pub depth_info: CameraInfo,
}

/// An RGB-D frame as a colour image (rgb8), a depth image (16UC1 in mm, 0 = no return, as
/// `depth_image_proc` expects) and both camera models.
pub fn camera_messages(frame: &RgbdFrame, stamp_ns: u64) -> CameraMessages {
    let color_header = Header::new(stamp_ns, COLOR_OPTICAL_FRAME);
    let depth_header = Header::new(stamp_ns, DEPTH_OPTICAL_FRAME);
    let depth_bytes: Vec<u8> = frame
        .depth_mm
        .iter()
        .flat_map(|depth| depth.to_le_bytes())
        .collect();
    CameraMessages {
        color: Image {
            header: color_header.clone(),
            height: RGB_HEIGHT_PX as u32,
            width: RGB_WIDTH_PX as u32,
            encoding: "rgb8".to_owned(),
            is_bigendian: 0,
            step: (RGB_WIDTH_PX * 3) as u32,
            data: frame.rgb.to_vec(),
        },
        color_info: camera_info(&frame.meta.rgb_intrinsics, color_header),
        depth: Image {
            header: depth_header.clone(),
            height: DEPTH_HEIGHT_PX as u32,
            width: DEPTH_WIDTH_PX as u32,
            encoding: "16UC1".to_owned(),
            is_bigendian: 0,
            step: (DEPTH_WIDTH_PX * 2) as u32,
            data: depth_bytes,
        },
        depth_info: camera_info(&frame.meta.depth_intrinsics, depth_header),
    }
}

/// The apples of one frame as `Detection3DArray` in the colour camera's frame, stamped with the
/// frame's capture time: per apple one hypothesis (`apple`, the confidence), the centre as the
/// pose, the bounding cube of the sphere as the box, the apple's track id as `id`.
pub fn detections(apples: &AppleDetections, stamp_ns: u64) -> Detection3DArray {
    let header = Header::new(stamp_ns, COLOR_OPTICAL_FRAME);
    let detections = apples
        .apples
        .iter()
        .map(|apple| {
            let [x, y, z] = apple.position_in_camera_m;
            let pose = Pose {
                position: Point { x, y, z },
                ..Pose::default()
            };
            let diameter_m = 2.0 * apple.radius_m;
            Detection3D {
                header: header.clone(),
                results: vec![ObjectHypothesisWithPose {
                    hypothesis: ObjectHypothesis {
                        class_id: APPLE_CLASS.to_owned(),
                        score: f64::from(apple.confidence),
                    },
                    pose: PoseWithCovariance {
                        pose,
                        ..PoseWithCovariance::default()
                    },
                }],
                bbox: BoundingBox3D {
                    center: pose,
                    size: Vector3 {
                        x: diameter_m,
                        y: diameter_m,
                        z: diameter_m,
                    },
                },
                id: apple.apple_id.to_string(),
            }
        })
        .collect();
    Detection3DArray { header, detections }
}

/// One arm's encoder feedback as `JointState` (positions and velocities, no effort).
pub fn joint_state(state: &ArmState, stamp_ns: u64) -> JointState {
    JointState {
        header: Header::new(stamp_ns, ROBOT_FRAME),
        name: joint_names(state.arm_id),
        position: state.joint_position.to_vec(),
        velocity: state.joint_velocity.to_vec(),
        effort: Vec::new(),
    }
}

/// A LiDAR cloud as `PointCloud2`: one row, fields x, y, z, intensity as float32 (the Livox ROS
/// driver's first four), 16 bytes a point, little endian.
pub fn point_cloud(cloud: &PointCloud, stamp_ns: u64) -> PointCloud2 {
    let points = cloud.valid_points();
    let mut data = Vec::with_capacity(points.len() * 16);
    for point in points {
        for value in [point.x_m, point.y_m, point.z_m, point.intensity] {
            data.extend_from_slice(&value.to_le_bytes());
        }
    }
    PointCloud2 {
        header: Header::new(stamp_ns, LIDAR_FRAME),
        height: 1,
        width: points.len() as u32,
        fields: ["x", "y", "z", "intensity"]
            .iter()
            .enumerate()
            .map(|(index, name)| PointField::scalar(name, 4 * index as u32, PointField::FLOAT32))
            .collect(),
        is_bigendian: false,
        point_step: 16,
        row_step: (points.len() * 16) as u32,
        data,
        is_dense: points.iter().all(|point| point.is_finite()),
    }
}
