//! The RIHS01 hashes and definitions against published values: the hashes ROS 2 Jazzy's own
//! golden-hash tests and `ros2 topic info -v` print for the standard types (the same values
//! the Python `rosbags` package computes from its Jazzy type store), so a Zenoh or DDS peer
//! and rosbag2 agree with ours.

use harvest_ros2::msgs::{
    builtin_interfaces, diagnostic_msgs, geometry_msgs, sensor_msgs, std_msgs, vision_msgs,
};
use harvest_ros2::type_description::MessageType;

const PUBLISHED: [(&MessageType, &str); 16] = [
    (
        &builtin_interfaces::TIME_TYPE,
        "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    ),
    (
        &std_msgs::HEADER_TYPE,
        "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    ),
    (
        // The type of rmw_zenoh's own talker example (`0/chatter/std_msgs::msg::dds_::String_/...`).
        &std_msgs::STRING_TYPE,
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    ),
    (
        &std_msgs::BOOL_TYPE,
        "RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9",
    ),
    (
        &sensor_msgs::IMAGE_TYPE,
        "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
    ),
    (
        &sensor_msgs::COMPRESSED_IMAGE_TYPE,
        "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a",
    ),
    (
        &sensor_msgs::CAMERA_INFO_TYPE,
        "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
    ),
    (
        &sensor_msgs::POINT_CLOUD2_TYPE,
        "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
    ),
    (
        &sensor_msgs::POINT_FIELD_TYPE,
        "RIHS01_5c6a4750728c2bcfbbf7037225b20b02d4429634732146b742dee1726637ef01",
    ),
    (
        &sensor_msgs::JOINT_STATE_TYPE,
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    ),
    (
        &diagnostic_msgs::DIAGNOSTIC_ARRAY_TYPE,
        "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
    ),
    (
        &diagnostic_msgs::DIAGNOSTIC_STATUS_TYPE,
        "RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4",
    ),
    (
        &diagnostic_msgs::KEY_VALUE_TYPE,
        "RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42",
    ),
    (
        &geometry_msgs::POSE_TYPE,
        "RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    ),
    (
        &geometry_msgs::POSE_WITH_COVARIANCE_TYPE,
        "RIHS01_9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb",
    ),
    (
        &vision_msgs::DETECTION_3D_ARRAY_TYPE,
        // No ROS install here: computed by `rosbags` (an independent implementation of the
        // same algorithm) from vision_msgs 4.1.1's .msg files.
        "RIHS01_793f5eab9595ac1c0da07873cc859db42eae51f0ee76056db8562515d830e018",
    ),
];

#[test]
fn type_hashes_match_the_published_values() {
    let mut wrong = Vec::new();
    for (ty, published) in PUBLISHED {
        let ours = ty.type_hash();
        if ours != published {
            wrong.push(format!("{}: ours {ours}, published {published}", ty.name));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn definitions_carry_every_dependency_once() {
    let text = sensor_msgs::CAMERA_INFO_TYPE.definition();
    assert!(text.starts_with("std_msgs/Header header\nuint32 height\n"));
    for dependency in [
        "MSG: std_msgs/Header\n",
        "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n",
        "MSG: sensor_msgs/RegionOfInterest\n",
    ] {
        assert_eq!(
            text.matches(dependency).count(),
            1,
            "{dependency} in\n{text}"
        );
    }
    assert!(text.contains("float64[9] k\n") && text.contains("float64[] d\n"));
    let point_field = sensor_msgs::POINT_FIELD_TYPE.own_definition();
    assert!(point_field.starts_with("uint8 INT8=1\n"));
    assert_eq!(
        geometry_msgs::QUATERNION_TYPE.own_definition(),
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
    );
    assert_eq!(
        sensor_msgs::IMAGE_TYPE.dds_name(),
        "sensor_msgs::msg::dds_::Image_"
    );
}
