//! The standard message types the stack exchanges, one module per ROS 2 package, field for
//! field as in the package's `.msg` files (ROS 2 Jazzy; vision_msgs 4.1).

pub mod builtin_interfaces;
pub mod diagnostic_msgs;
pub mod geometry_msgs;
pub mod sensor_msgs;
pub mod std_msgs;
pub mod vision_msgs;

use crate::type_description::MessageType;

/// Every message type of this crate (for listings and the hash checks).
pub fn all_types() -> Vec<&'static MessageType> {
    vec![
        &builtin_interfaces::TIME_TYPE,
        &std_msgs::HEADER_TYPE,
        &std_msgs::BOOL_TYPE,
        &sensor_msgs::IMAGE_TYPE,
        &sensor_msgs::COMPRESSED_IMAGE_TYPE,
        &sensor_msgs::CAMERA_INFO_TYPE,
        &sensor_msgs::REGION_OF_INTEREST_TYPE,
        &sensor_msgs::POINT_FIELD_TYPE,
        &sensor_msgs::POINT_CLOUD2_TYPE,
        &sensor_msgs::JOINT_STATE_TYPE,
        &geometry_msgs::POINT_TYPE,
        &geometry_msgs::QUATERNION_TYPE,
        &geometry_msgs::VECTOR3_TYPE,
        &geometry_msgs::POSE_TYPE,
        &geometry_msgs::POSE_WITH_COVARIANCE_TYPE,
        &diagnostic_msgs::KEY_VALUE_TYPE,
        &diagnostic_msgs::DIAGNOSTIC_STATUS_TYPE,
        &diagnostic_msgs::DIAGNOSTIC_ARRAY_TYPE,
        &vision_msgs::OBJECT_HYPOTHESIS_TYPE,
        &vision_msgs::OBJECT_HYPOTHESIS_WITH_POSE_TYPE,
        &vision_msgs::BOUNDING_BOX_3D_TYPE,
        &vision_msgs::DETECTION_3D_TYPE,
        &vision_msgs::DETECTION_3D_ARRAY_TYPE,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cdr::Endianness;
    use crate::message::RosMessage;
    use sensor_msgs::{CameraInfo, Image, JointState, PointCloud2, PointField};
    use std_msgs::Header;

    fn round_trip<T: RosMessage + PartialEq + std::fmt::Debug>(message: &T) {
        for endianness in [Endianness::Little, Endianness::Big] {
            let bytes = message.to_cdr_in(endianness);
            assert_eq!(&T::from_cdr(&bytes).unwrap(), message, "{endianness:?}");
            // Every cut of the message is refused, never a panic.
            for cut in [0, 3, 4, bytes.len() / 2, bytes.len() - 1] {
                if cut < bytes.len() {
                    assert!(T::from_cdr(&bytes[..cut]).is_err() || cut >= bytes.len() - 3);
                }
            }
        }
    }

    #[test]
    fn messages_round_trip_in_both_byte_orders() {
        let header = Header::new(1_700_000_000_123_456_789, "camera_color_optical_frame");
        round_trip(&Image {
            header: header.clone(),
            height: 2,
            width: 3,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: 9,
            data: (0..18).collect(),
        });
        round_trip(&CameraInfo {
            header: header.clone(),
            height: 480,
            width: 640,
            distortion_model: "plumb_bob".into(),
            d: vec![-0.04, 0.01, 0.0, 0.0, 0.0],
            k: [500.0, 0.0, 319.5, 0.0, 500.0, 239.5, 0.0, 0.0, 1.0],
            ..CameraInfo::default()
        });
        round_trip(&PointCloud2 {
            header: header.clone(),
            height: 1,
            width: 1,
            fields: vec![PointField::scalar("x", 0, PointField::FLOAT32)],
            is_bigendian: false,
            point_step: 4,
            row_step: 4,
            data: vec![0, 0, 128, 63],
            is_dense: true,
        });
        round_trip(&JointState {
            header: header.clone(),
            name: vec!["q1".into(), "q2".into()],
            position: vec![0.5, -1.0],
            velocity: vec![],
            effort: vec![],
        });
        round_trip(&vision_msgs::Detection3DArray {
            header: header.clone(),
            detections: vec![vision_msgs::Detection3D {
                header,
                results: vec![vision_msgs::ObjectHypothesisWithPose::default()],
                bbox: vision_msgs::BoundingBox3D::default(),
                id: "17".into(),
            }],
        });
    }

    #[test]
    fn a_header_has_the_bytes_ros_writes() {
        // stamp {sec: 1, nanosec: 2}, frame_id "ab": little endian, aligned from the header.
        let bytes = Header::new(1_000_000_002, "ab").to_cdr();
        assert_eq!(
            bytes,
            [
                0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0, b'a', b'b', 0
            ]
        );
    }
}
