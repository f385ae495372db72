//! harvest-ros2: ROS 2 messages without ROS. Pure and transport-free: no rmw, no DDS, no
//! network, no knowledge of the stack's channels (the mapping lives elsewhere), so any bridge
//! (rosbag2 files, rmw_zenoh, DDS) can use it.
//!
//! - [`cdr`]: plain CDR (XCDR1) with the 4-byte encapsulation header, both byte orders.
//! - [`type_description`]: a message type as data; from it the `.msg` definition text (MCAP
//!   schema encoding `ros2msg`) and the RIHS01 type hash.
//! - [`message`]: the [`RosMessage`] trait; [`msgs`]: the standard types (builtin_interfaces,
//!   std_msgs, sensor_msgs, geometry_msgs, diagnostic_msgs, vision_msgs).
//! - [`rosbag2`]: writing rosbag2 bags in MCAP storage (reading them is plain MCAP reading plus
//!   [`RosMessage::from_cdr`]).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod cdr;
pub mod message;
pub mod msgs;
pub mod rosbag2;
pub mod type_description;

pub use message::{DecodeError, RosMessage};
pub use type_description::MessageType;
