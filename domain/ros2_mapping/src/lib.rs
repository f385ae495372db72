//! harvest-ros2-mapping: the stack's channels to and from standard ROS 2 messages
//! ([`harvest_ros2`]), pure (no transport, no files but the map file's text).
//!
//! Out (a recording to a ROS 2 bag, [`to_ros`]):
//!
//! | stack channel | ROS 2 topic and type |
//! |---|---|
//! | `camera/rgbd` | `/camera/color/image_raw` `sensor_msgs/Image` (rgb8), `/camera/color/camera_info`, `/camera/depth/image_raw` (16UC1, mm), `/camera/depth/camera_info` |
//! | `perception/apples` | `/perception/apples` `vision_msgs/Detection3DArray` (colour camera frame) |
//! | `armN/state` | `/armN/joint_states` `sensor_msgs/JointState` |
//! | `lidar/points` | `/lidar/points` `sensor_msgs/PointCloud2` (x, y, z, intensity float32) |
//!
//! In (a bag into the stack's channels, [`from_ros`]): the topics a map file ([`map_file`])
//! names become `camera/rgbd` (colour and depth paired by stamp, [`frame_assembler`]) and
//! `lidar/points`. Whatever the stack cannot take is refused with an error naming the topic and
//! the field ([`error`]).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod camera_info;
pub mod error;
pub mod frame_assembler;
pub mod frames;
pub mod from_ros;
pub mod map_file;
pub mod to_ros;

pub use error::{FieldError, ImportError};
