//! The frame names of every mapped message, declared once.
//!
//! Convention (robotics right-handed frames, metres):
//! - `robot`: the eq. 1 frame of `harvest-robot-model` (x forward toward the canopy, y left, z up);
//!   the fixed frame of the 3D view. Apples, arm targets and the robot model live here.
//! - `camera_color`: the ToF camera's colour sensor (x right, y down, z forward, the optical
//!   frame); its pose in `robot` is the calibration file's `robot_from_camera`.
//! - `camera_depth`: the ToF camera's depth sensor; its pose in `camera_color` is the frame's
//!   registration `color_from_depth`.
//! - `lidar`: the solid-state LiDAR (x forward along the boresight, y left, z up); its pose in
//!   `camera_color` is the extrinsic file's `camera_from_lidar`.
//! - `arm1_link1` .. `arm1_link3`, `arm1_end_effector` (and the same for `arm2_`): the tube
//!   arm's kinematic chain (eq. 1), one frame per joint:
//!   - `armN_link1`: the carriage after the prismatic joint `D`, at `(x0 + D, y0, z0)` in `robot`,
//!     axes parallel to `robot`;
//!   - `armN_link2`: the pitched frame, `link1` rotated by `theta` (pitch up for positive theta,
//!     i.e. a rotation of `-theta` about `link1`'s y axis);
//!   - `armN_link3`: the yaw axis at `(x1, y1, z1)` in `link2`, rotated by `phi` (tip toward -y
//!     for positive phi, a rotation of `-phi` about `link2`'s z axis); the tube runs along its x;
//!   - `armN_end_effector`: the tube's tip at `(x2, 0, 0)` in `link3`, twisted by the end-effector
//!     rotation about the tube axis (x).
//!
//! Composing the four transforms of an arm puts `armN_end_effector`'s origin at eq. 1's
//! `p_e` and `armN_link3`'s at the yaw pivot (tested in [`crate::arm_frames`]).

use harvest_ipc::ArmId;

/// The robot body; the fixed frame.
pub const ROBOT: &str = "robot";
/// The ToF camera's colour sensor (optical frame).
pub const CAMERA_COLOR: &str = "camera_color";
/// The ToF camera's depth sensor (optical frame).
pub const CAMERA_DEPTH: &str = "camera_depth";
/// The solid-state LiDAR.
pub const LIDAR: &str = "lidar";

/// The frames of one arm's kinematic chain, from the robot body outward.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ArmFrames {
    /// After the prismatic joint.
    pub link1: &'static str,
    /// After the pitch joint.
    pub link2: &'static str,
    /// After the yaw joint (the tube's root).
    pub link3: &'static str,
    /// The tube's tip, after the twist.
    pub end_effector: &'static str,
}

const ARM_FRAMES: [ArmFrames; 2] = [
    ArmFrames {
        link1: "arm1_link1",
        link2: "arm1_link2",
        link3: "arm1_link3",
        end_effector: "arm1_end_effector",
    },
    ArmFrames {
        link1: "arm2_link1",
        link2: "arm2_link2",
        link3: "arm2_link3",
        end_effector: "arm2_end_effector",
    },
];

/// The chain frames of `arm`.
pub fn arm(arm: ArmId) -> ArmFrames {
    ARM_FRAMES[arm.index()]
}
