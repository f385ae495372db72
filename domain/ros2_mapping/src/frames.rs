//! The coordinate frame names the ROS 2 messages carry (`header.frame_id`): those of common ROS
//! drivers, so a ROS user's tf tree can name them.

/// The colour camera's optical frame (x right, y down, z forward, as the stack's camera frame).
pub const COLOR_OPTICAL_FRAME: &str = "camera_color_optical_frame";
/// The depth camera's optical frame.
pub const DEPTH_OPTICAL_FRAME: &str = "camera_depth_optical_frame";
/// The LiDAR frame (the Livox ROS driver's default name; x forward, y left, z up).
pub const LIDAR_FRAME: &str = "livox_frame";
/// The robot frame of the arms' joint states.
pub const ROBOT_FRAME: &str = "base_link";
